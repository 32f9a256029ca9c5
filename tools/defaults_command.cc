// `flysfm defaults`: every option's default as the code defines it, as the
// Markdown page docs/defaults.md (tools/defaults.h).

#include <iostream>

#include "tools/commands.h"
#include "tools/defaults.h"

namespace flysfm {

void AddDefaultsCommand(CLI::App& app) {
  CLI::App* command = app.add_subcommand(
      "defaults", "Print every option struct's defaults as Markdown, the content of "
                  "docs/defaults.md (build/flysfm defaults > docs/defaults.md)");
  command->callback([]() { std::cout << RenderOptionDefaults(ListOptionDefaults()); });
}

}  // namespace flysfm
