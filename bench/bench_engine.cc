// The engine on TUM freiburg1_xyz (330 frames, its calibration), fed as
// `flysfm batch` feeds it (the run loop, the next frame decoded and its
// features extracted on the second core): per-image time with every stage
// included and each stage's median, whether it stays flat as the model grows
// (the median of the last 100 frames over frames 50-150), the end's time
// (from the last frame's result to the written model), peak resident memory,
// and the accuracy reached (ATE after Sim3). With --ablation, the same for
// the full pipeline and with each of the paper's components switched off in
// turn. Ends with one line of JSON.
//
//   bench_engine [--frames N] [--data DIR] [--shuffle SEED] [--interval S] [--ablation]

#include <cstdio>
#include <iostream>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include "bench/bench_session.h"
#include "core/ablation.h"
#include "core/engine.h"
#include "core/malloc_policy.h"
#include "geometry/statistics.h"
#include "io/evaluation/evaluation.h"
#include "io/formats/trajectory.h"
#include "io/sources/image_source.h"

namespace flysfm {
namespace {

const char* const kFr1Camera =
    "FULL_OPENCV 517.3,516.5,318.6,255.3,0.2624,-0.9531,-0.0054,0.0026,1.1633,0,0,0";

struct Run {
  std::string name;
  bench::Session session;
  int frames = 0;
  int registered = 0;
  double ate_m = -1;
  double reprojection_px = 0;
  int points = 0;
  double mean_track_length = 0;
  double growth = 0;  // all stages, median of the last 100 / frames 50-150
  std::string ate_report;
};

Run RunEngineOn(const std::string& name, const Engine::Options& options,
                const std::vector<Frame>& frames, const std::vector<StampedPose>& truth,
                double interval_s, bool verbose) {
  Engine engine(options, Camera::FromString(kFr1Camera, 0, 0));
  bench::SessionOptions session_options;
  session_options.run.print = verbose;
  session_options.interval_s = interval_s;
  if (interval_s == 0) {
    session_options.run.between_images = RunLoop::Options::BetweenImages::kNothing;
  }
  Run run;
  run.name = name;
  run.session = bench::RunSession(&engine, frames, session_options);
  const Reconstruction& model = engine.reconstruction();
  run.frames = int(frames.size());
  run.registered = int(model.NumRegisteredImages());
  run.reprojection_px = model.MeanReprojectionError();
  run.points = int(model.NumPoints3D());
  run.mean_track_length = model.MeanTrackLength();
  run.growth = bench::Growth(run.session.all_stages_ms, 50, 100);
  const TrajectoryEvaluation evaluation = EvaluateTrajectory(TrajectoryOf(model), truth);
  run.ate_m = evaluation.ate ? evaluation.ate->rmse : -1.0;
  run.ate_report = evaluation.Report();
  return run;
}

nlohmann::json ToJson(const Run& run) {
  nlohmann::json json = bench::SessionJson(run.session);
  json.update({{"name", run.name},
               {"frames", run.frames},
               {"registered", run.registered},
               {"ate_rmse_m", run.ate_m},
               {"mean_reprojection_error_px", run.reprojection_px},
               {"points", run.points},
               {"mean_track_length", run.mean_track_length},
               {"growth_last100_over_50_150", run.growth}});
  return json;
}

void PrintAblationTable(const std::vector<Run>& runs) {
  std::printf("\n| configuration | registered | ATE RMSE (cm) | reprojection (px) | "
              "track length | median all-stages ms | the end s |\n"
              "|---|---|---|---|---|---|---|\n");
  for (const Run& run : runs) {
    std::printf("| %s | %d/%d | %.2f | %.3f | %.1f | %.0f | %.1f |\n", run.name.c_str(),
                run.registered, run.frames, 100 * run.ate_m, run.reprojection_px,
                run.mean_track_length, Median(run.session.all_stages_ms),
                run.session.run.end_s);
  }
}

}  // namespace
}  // namespace flysfm

int main(int argc, char** argv) {
  using namespace flysfm;
  ApplyMallocPolicy();  // as flysfm does: the engine measured as it runs there
  CLI::App app("The engine on TUM freiburg1_xyz as `flysfm batch` runs it");
  int num_frames = 330;
  int shuffle_seed = -1;
  double interval_s = 0;
  bool ablation = false;
  std::string data;
  app.add_option("--frames", num_frames, "Frames of the sequence (0: all)")->capture_default_str();
  app.add_option("--shuffle", shuffle_seed, "Random order from this seed; -1: capture order")
      ->capture_default_str();
  app.add_option("--interval", interval_s,
                 "Seconds between frames (refinement between them); 0: unpaced, as fast as "
                 "the engine goes")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  app.add_flag("--ablation", ablation, "Also each of the paper's components switched off");
  bench::AddDataOption(&app, &data);
  CLI11_PARSE(app, argc, argv);

  const std::string dir = data + "/tum/rgbd_dataset_freiburg1_xyz";
  std::vector<Frame> frames;
  std::vector<StampedPose> truth;
  try {
    frames = ListTumSequence(dir);
    truth = ReadTumTrajectory(dir + "/groundtruth.txt");
  } catch (const std::exception& e) {
    std::cerr << "bench_engine: " << e.what() << " (set FLYSFM_DATA or --data)\n";
    return 2;
  }
  if (num_frames > 0 && int(frames.size()) > num_frames) frames.resize(num_frames);
  if (shuffle_seed >= 0) ShuffleFrames(&frames, std::uint32_t(shuffle_seed));

  const Run full =
      RunEngineOn("full pipeline", Engine::Options(), frames, truth, interval_s, !ablation);
  std::printf("\nframes %d%s, registered %d, mean reprojection error %.3f px, %d points of mean "
              "track length %.1f\n",
              full.frames, shuffle_seed >= 0 ? " (shuffled)" : " (in order)", full.registered,
              full.reprojection_px, full.points, full.mean_track_length);
  bench::PrintSessionFigures(full.session, "full pipeline");
  std::printf("growth, all stages, median of the last 100 frames / frames 50-150: %.2f\n%s",
              full.growth, full.ate_report.c_str());

  nlohmann::json json = {{"bench", "engine"}, {"interval_s", interval_s}, {"full", ToJson(full)}};
  if (ablation) {
    std::vector<Run> runs = {full};
    for (const EngineAblation& switched_off : EngineAblations()) {
      Engine::Options options;
      switched_off.apply(&options);
      runs.push_back(RunEngineOn(switched_off.name, options, frames, truth, interval_s, false));
    }
    PrintAblationTable(runs);
    json["ablation"] = nlohmann::json::array();
    for (const Run& run : runs) json["ablation"].push_back(ToJson(run));
  }
  std::cout << json.dump() << "\n";
  return 0;
}
