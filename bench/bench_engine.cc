// The engine on TUM freiburg1_xyz (330 frames, its calibration): per-image
// time (median, p95, each stage's median), whether it stays flat as the model
// grows (median of the last 100 frames against frames 50-150), and the
// accuracy reached (ATE after Sim3). With --ablation, the same for the full
// pipeline and with each of the paper's components switched off in turn.
// Ends with one line of JSON.
//
//   bench_engine [--frames N] [--data DIR] [--shuffle SEED] [--ablation]
//
// Frames are fed as the batch command feeds them: the next frame is decoded
// and its features extracted on the second core while the engine works
// (io/sources/prepared_source.h). Two per-image times are reported: the
// engine's (AddImage of a prepared frame: what bounds the frame rate) and the
// work of all stages including decoding and features, wherever they ran.

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <functional>
#include <iostream>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "core/ablation.h"
#include "core/engine.h"
#include "core/malloc_policy.h"
#include "io/evaluation/evaluation.h"
#include "io/formats/trajectory.h"
#include "io/run/run_writer.h"
#include "io/sources/image_source.h"
#include "io/sources/prepared_source.h"

namespace flysfm {
namespace {

double Median(std::vector<double> values) {
  if (values.empty()) return 0;
  std::sort(values.begin(), values.end());
  const std::size_t n = values.size();
  return n % 2 ? values[n / 2] : 0.5 * (values[n / 2 - 1] + values[n / 2]);
}

struct Run {
  std::string name;
  int frames = 0;
  int registered = 0;
  double ate_m = -1;
  double reprojection_px = 0;
  int points = 0;
  double mean_track_length = 0;
  double median_engine_ms = 0;  // per frame, AddImage of the prepared frame
  double median_work_ms = 0;    // per frame, every stage
  double p95_engine_ms = 0;
  double flatness = 0;  // median engine time of the last 100 / frames 50-150
  double wall_s = 0;
  nlohmann::json stages;
  std::string ate_report;
};

Run RunEngineOn(const std::string& name, const Engine::Options& options,
                const std::vector<Frame>& frames, const std::vector<StampedPose>& truth,
                bool verbose) {
  const auto start = std::chrono::steady_clock::now();
  Engine engine(options,
                Camera::FromString("FULL_OPENCV 517.3,516.5,318.6,255.3,0.2624,-0.9531,"
                                   "-0.0054,0.0026,1.1633,0,0,0",
                                   0, 0));
  FrameListSource source(frames);
  PreparedFrameSource prepared(&source, options);
  std::vector<ImageResult> results;
  std::vector<double> engine_ms, work_ms;
  while (std::optional<PreparedFrame> frame = prepared.Next()) {
    const auto call = std::chrono::steady_clock::now();
    std::vector<ImageResult> out = engine.AddImage(std::move(*frame));
    engine_ms.push_back(
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - call)
            .count());
    work_ms.push_back(out.front().times.total);
    if (verbose) {
      std::printf("%-28s %-10s engine %6.0f ms, all stages %6.0f ms\n", out.front().name.c_str(),
                  ImageStatusName(out.front().status), engine_ms.back(), work_ms.back());
    }
    results.insert(results.end(), out.begin(), out.end());
  }
  engine.Finish();
  const Reconstruction& model = engine.reconstruction();

  Run run;
  run.name = name;
  run.frames = int(frames.size());
  run.registered = int(model.NumRegisteredImages());
  run.reprojection_px = model.MeanReprojectionError();
  run.points = int(model.NumPoints3D());
  run.mean_track_length = model.MeanTrackLength();
  run.median_engine_ms = Median(engine_ms);
  run.median_work_ms = Median(work_ms);
  std::vector<double> sorted = engine_ms;
  std::sort(sorted.begin(), sorted.end());
  run.p95_engine_ms = sorted.empty() ? 0 : sorted[std::size_t(0.95 * (sorted.size() - 1))];
  const auto window = [&](std::size_t begin, std::size_t end) {
    end = std::min(end, engine_ms.size());
    begin = std::min(begin, end);
    return Median(std::vector<double>(engine_ms.begin() + begin, engine_ms.begin() + end));
  };
  const double mid = window(50, 150);
  const double last = window(engine_ms.size() >= 100 ? engine_ms.size() - 100 : 0,
                             engine_ms.size());
  run.flatness = mid > 0 ? last / mid : 0;
  run.stages = StageTimeStatistics(results);
  const TrajectoryEvaluation evaluation = EvaluateTrajectory(TrajectoryOf(model), truth);
  run.ate_m = evaluation.ate ? evaluation.ate->rmse : -1.0;
  run.ate_report = evaluation.Report();
  run.wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return run;
}

nlohmann::json ToJson(const Run& run) {
  return {{"name", run.name},
          {"frames", run.frames},
          {"registered", run.registered},
          {"ate_rmse_m", run.ate_m},
          {"mean_reprojection_error_px", run.reprojection_px},
          {"points", run.points},
          {"mean_track_length", run.mean_track_length},
          {"median_engine_ms", run.median_engine_ms},
          {"p95_engine_ms", run.p95_engine_ms},
          {"median_all_stages_ms", run.median_work_ms},
          {"flatness_last100_over_50_150", run.flatness},
          {"stage_ms", run.stages}};
}

}  // namespace
}  // namespace flysfm

int main(int argc, char** argv) {
  using namespace flysfm;
  ApplyMallocPolicy();  // as flysfm does: the engine measured as it runs there
  int num_frames = 330;
  int shuffle_seed = -1;
  bool ablation = false;
  std::string data = std::getenv("FLYSFM_DATA") ? std::getenv("FLYSFM_DATA")
                                                : FLYSFM_DEFAULT_DATA_DIR;
  for (int i = 1; i < argc; ++i) {
    const bool has_value = i + 1 < argc;
    if (!std::strcmp(argv[i], "--frames") && has_value) {
      num_frames = std::atoi(argv[++i]);
    } else if (!std::strcmp(argv[i], "--data") && has_value) {
      data = argv[++i];
    } else if (!std::strcmp(argv[i], "--shuffle") && has_value) {
      shuffle_seed = std::atoi(argv[++i]);
    } else if (!std::strcmp(argv[i], "--ablation")) {
      ablation = true;
    } else {
      std::cerr << "usage: bench_engine [--frames N] [--data DIR] [--shuffle SEED] "
                   "[--ablation]\n";
      return 2;
    }
  }
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

  const Run full = RunEngineOn("full pipeline", Engine::Options(), frames, truth, !ablation);
  std::cout << "\nframes " << full.frames << (shuffle_seed >= 0 ? " (shuffled)" : " (in order)")
            << ", registered " << full.registered << ", mean reprojection error "
            << full.reprojection_px << " px, " << full.points << " points of mean track length "
            << full.mean_track_length << "; " << full.wall_s << " s in all\n"
            << "per-image engine time (features prepared ahead on the 2nd core): median "
            << full.median_engine_ms << " ms, p95 " << full.p95_engine_ms
            << " ms (target: median <= 300 ms)\n"
            << "per-image time of all stages: median " << full.median_work_ms << " ms\n";
  for (const auto& [stage, figures] : full.stages.items()) {
    std::cout << "  " << stage << ": median " << figures["median"].get<double>() << " ms\n";
  }
  std::cout << "engine time of the last 100 frames / frames 50-150: " << full.flatness
            << " (target <= 1.5)\n"
            << full.ate_report;

  nlohmann::json json = {{"bench", "engine"}, {"full", ToJson(full)}};
  if (ablation) {
    std::vector<Run> runs = {full};
    for (const EngineAblation& ablation : EngineAblations()) {
      Engine::Options options;
      ablation.apply(&options);
      runs.push_back(RunEngineOn(ablation.name, options, frames, truth, false));
    }
    std::printf("\n| configuration | registered | ATE RMSE (cm) | reprojection (px) | "
                "track length | median engine ms | median all-stages ms |\n"
                "|---|---|---|---|---|---|---|\n");
    for (const Run& run : runs) {
      std::printf("| %s | %d/%d | %.2f | %.3f | %.1f | %.0f | %.0f |\n", run.name.c_str(),
                  run.registered, run.frames, 100 * run.ate_m, run.reprojection_px,
                  run.mean_track_length, run.median_engine_ms, run.median_work_ms);
    }
    json["ablation"] = nlohmann::json::array();
    for (const Run& run : runs) json["ablation"].push_back(ToJson(run));
  }
  std::cout << json.dump() << "\n";
  return 0;
}
