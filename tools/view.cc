// `flysfm view OUT`: the live view of a finished run, its model read from
// OUT/sparse, served until Ctrl-C.

#include <filesystem>
#include <fstream>
#include <iostream>

#include <nlohmann/json.hpp>

#include "io/formats/colmap_model.h"
#include "quality/coverage.h"
#include "quality/quality_tracker.h"
#include "tools/commands.h"
#include "tools/view_flags.h"

namespace flysfm {
namespace {

// The quality options a run wrote into summary.json ("quality"); the
// defaults for what it does not say (an older or a hand-made folder).
QualityTracker::Options QualityOptionsOf(const nlohmann::json& summary) {
  QualityTracker::Options options;
  if (!summary.contains("quality") || !summary["quality"].is_object()) return options;
  const nlohmann::json& quality = summary["quality"];
  if (quality.contains("sigma_px") && quality["sigma_px"].is_number()) {
    options.sigma_px = quality["sigma_px"].get<double>();
  }
  if (quality.contains("sigma_source") && quality["sigma_source"].is_string()) {
    if (const auto source = SigmaSourceFromName(quality["sigma_source"].get<std::string>())) {
      options.sigma_source = *source;
    }
  }
  if (quality.contains("prior_redundancy") && quality["prior_redundancy"].is_number()) {
    options.prior_redundancy = quality["prior_redundancy"].get<double>();
  }
  if (quality.contains("min_views") && quality["min_views"].is_number_integer()) {
    options.min_views = quality["min_views"].get<int>();
  }
  if (quality.contains("min_angle_deg") && quality["min_angle_deg"].is_number()) {
    options.min_angle_deg = quality["min_angle_deg"].get<double>();
  }
  try {
    options.Check();
  } catch (const std::invalid_argument&) {
    return QualityTracker::Options();  // a damaged summary: the defaults
  }
  return options;
}

}  // namespace

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
      std::ifstream summary_file(std::filesystem::path(flags->out) / "summary.json");
      nlohmann::json summary;
      if (summary_file) summary = nlohmann::json::parse(summary_file, nullptr, false);
      if (!summary.is_object()) summary = nlohmann::json::object();
      // The model measured as the run measured it, so that the page's
      // coverage agrees with its summary.json.
      QualityTracker quality(QualityOptionsOf(summary));
      quality.Rebuild(model);
      Coverage::Options coverage_options;
      coverage_options.min_views = quality.options().min_views;
      coverage_options.min_angle_deg = quality.options().min_angle_deg;
      Coverage coverage(coverage_options);
      coverage.Update(model);
      ViewUpdate update = MakeFullViewUpdate(model, &quality, &coverage);
      // The images the run left waiting, from its summary (no reasons kept there).
      if (summary.contains("pending") && summary["pending"].is_array()) {
        for (const nlohmann::json& name : summary["pending"]) {
          if (!name.is_string()) continue;
          ViewLine line;
          line.name = name.get<std::string>();
          line.status = ImageStatusName(ImageStatus::kPending);
          line.reason = "still pending when the run ended";
          update.lines.push_back(line);
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
