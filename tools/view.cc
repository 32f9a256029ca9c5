// `flysfm view OUT`: the live view of a finished run, its model read from
// OUT/sparse, served until Ctrl-C.

#include <filesystem>
#include <fstream>
#include <iostream>

#include <nlohmann/json.hpp>

#include "io/formats/colmap_model.h"
#include "tools/commands.h"
#include "tools/view_flags.h"

namespace flysfm {

void AddViewCommand(CLI::App& app) {
  struct Flags {
    std::string out;
    int port = ViewFlags::kDefaultViewPort;
    bool lan = false;
  };
  auto flags = std::make_shared<Flags>();
  CLI::App* command = app.add_subcommand(
      "view", "Serve the 3D view of a finished run's model (OUT/sparse) in the browser "
              "until Ctrl-C");
  command->add_option("out", flags->out, "The run's output folder (--out of batch or live)")
      ->required();
  command->add_option("--port", flags->port, "HTTP port (0: any free port)")
      ->check(CLI::Range(0, 65535))
      ->capture_default_str();
  command->add_flag("--lan", flags->lan,
                    "Serve on every network interface, protected by a printed token");
  command->callback([flags]() {
    try {
      const std::filesystem::path sparse = std::filesystem::path(flags->out) / "sparse";
      if (!std::filesystem::is_directory(sparse)) {
        throw std::invalid_argument(sparse.string() + " is not a folder: is " + flags->out +
                                    " the --out of a run?");
      }
      const Reconstruction model = ReadColmapModel(sparse);
      ViewFlags view_flags;
      view_flags.port = flags->port;
      view_flags.lan = flags->lan;
      const std::unique_ptr<ViewServer> server = StartView(view_flags);
      ViewUpdate update = MakeFullViewUpdate(model);
      // The images the run left waiting, from its summary (no reasons kept there).
      std::ifstream summary_file(std::filesystem::path(flags->out) / "summary.json");
      if (summary_file) {
        const nlohmann::json summary = nlohmann::json::parse(summary_file, nullptr, false);
        if (summary.is_object() && summary.contains("pending") && summary["pending"].is_array()) {
          for (const nlohmann::json& name : summary["pending"]) {
            if (!name.is_string()) continue;
            ViewLine line;
            line.name = name.get<std::string>();
            line.status = ImageStatusName(ImageStatus::kPending);
            line.reason = "still pending when the run ended";
            update.lines.push_back(line);
          }
        }
      }
      server->Publish(update);
      server->Finish(0.0);
      std::printf("view: %zu images, %zu points from %s; Ctrl-C to stop\n",
                  model.NumRegisteredImages(), model.NumPoints3D(), sparse.c_str());
      std::fflush(stdout);
      WaitForInterrupt();
    } catch (const std::invalid_argument& e) {
      std::cerr << "flysfm view: " << e.what() << "\n";
      throw CLI::RuntimeError(2);
    } catch (const std::exception& e) {
      std::cerr << "flysfm view: " << e.what() << "\n";
      throw CLI::RuntimeError(1);
    }
  });
}

}  // namespace flysfm
