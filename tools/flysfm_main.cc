// The flysfm command-line program. Sub-commands are registered by the tools
// that provide them (tools/commands.h); each prints its options with their
// defaults on --help.

#include <iostream>

#include <CLI/CLI.hpp>

#include "core/malloc_policy.h"
#include "tools/commands.h"

int main(int argc, char** argv) {
  // Before any thread starts (core/malloc_policy.h); where the allocator
  // refuses, the program runs as before, only slower.
  flysfm::ApplyMallocPolicy();
  CLI::App app{
      "flysfm: on-the-fly Structure-from-Motion. Each image is registered "
      "(pose, new 3D points) as it arrives."};
  app.set_version_flag("--version", "flysfm 0.1.0");
  app.require_subcommand(0, 1);
  flysfm::AddBatchCommand(app);
  flysfm::AddCamfiEmulatorCommand(app);
  flysfm::AddDefaultsCommand(app);
  flysfm::AddDemoCommand(app);
  flysfm::AddEvalCommand(app);
  flysfm::AddLiveCommand(app);
  flysfm::AddTrainRetrievalCommand(app);
  flysfm::AddViewCommand(app);
  // A command's error that no command caught (the output folder in use,
  // say) is a one-line message, not std::terminate.
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e);
  } catch (const std::exception& e) {
    std::cerr << "flysfm: " << e.what() << "\n";
    return 1;
  }
  if (app.get_subcommands().empty()) {
    std::cout << app.help();
  }
  return 0;
}
