// The engine on TUM freiburg1_xyz (330 frames, its calibration, in order):
// per-image time (median, p95, each stage's median), whether it stays flat
// as the model grows (median of the last 100 frames against frames 50-150),
// and the accuracy reached (ATE after Sim3). Ends with one line of JSON.
//
//   bench_engine [--frames N] [--data DIR]

#include <algorithm>
#include <cstdlib>
#include <cstring>
#include <iostream>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "core/engine.h"
#include "io/evaluation.h"
#include "io/image_source.h"
#include "io/run_writer.h"

namespace {

double Median(std::vector<double> values) {
  if (values.empty()) return 0;
  std::sort(values.begin(), values.end());
  const std::size_t n = values.size();
  return n % 2 ? values[n / 2] : 0.5 * (values[n / 2 - 1] + values[n / 2]);
}

}  // namespace

int main(int argc, char** argv) {
  using namespace flysfm;
  int num_frames = 330;
  std::string data = std::getenv("FLYSFM_DATA") ? std::getenv("FLYSFM_DATA")
                                                : FLYSFM_DEFAULT_DATA_DIR;
  for (int i = 1; i + 1 < argc; i += 2) {
    if (!std::strcmp(argv[i], "--frames")) num_frames = std::atoi(argv[i + 1]);
    if (!std::strcmp(argv[i], "--data")) data = argv[i + 1];
  }
  const std::string dir = data + "/tum/rgbd_dataset_freiburg1_xyz";
  std::vector<Frame> frames;
  try {
    frames = ListTumSequence(dir);
  } catch (const std::exception& e) {
    std::cerr << "bench_engine: " << e.what() << " (set FLYSFM_DATA or --data)\n";
    return 2;
  }
  if (num_frames > 0 && int(frames.size()) > num_frames) frames.resize(num_frames);

  Engine engine(Engine::Options(),
                Camera::FromString("FULL_OPENCV 517.3,516.5,318.6,255.3,0.2624,-0.9531,"
                                   "-0.0054,0.0026,1.1633,0,0,0",
                                   0, 0));
  // Per input frame, the time of its own AddImage call (what a live user
  // waits for), in arrival order.
  std::vector<ImageResult> results;
  std::vector<double> call_ms;
  for (const Frame& frame : frames) {
    std::vector<ImageResult> out = engine.AddImage(frame);
    call_ms.push_back(out.front().times.total);
    std::cout << frame.name << " " << ImageStatusName(out.front().status) << " "
              << out.front().times.total << " ms\n";
    results.insert(results.end(), out.begin(), out.end());
  }
  engine.Finish();
  const Reconstruction& model = engine.reconstruction();

  const auto window = [&](std::size_t begin, std::size_t end) {
    end = std::min(end, call_ms.size());
    begin = std::min(begin, end);
    return Median(std::vector<double>(call_ms.begin() + begin, call_ms.begin() + end));
  };
  const double mid = window(50, 150);
  const double last = window(call_ms.size() >= 100 ? call_ms.size() - 100 : 0, call_ms.size());
  const nlohmann::json stages = StageTimeStatistics(results);
  const TrajectoryEvaluation evaluation = EvaluateTrajectory(
      TrajectoryOf(model), ReadTumTrajectory(dir + "/groundtruth.txt"));

  std::cout << "\nframes " << frames.size() << ", registered " << model.NumRegisteredImages()
            << ", points " << model.NumPoints3D() << ", mean reprojection error "
            << model.MeanReprojectionError() << " px\n";
  std::cout << "per-image total: median " << Median(call_ms) << " ms, p95 "
            << stages["total"]["p95"].get<double>() << " ms (target: median <= 300 ms)\n";
  for (const auto& [stage, figures] : stages.items()) {
    std::cout << "  " << stage << ": median " << figures["median"].get<double>() << " ms\n";
  }
  std::cout << "median of frames 50-150: " << mid << " ms; of the last 100: " << last
            << " ms; ratio " << (mid > 0 ? last / mid : 0) << " (target <= 1.5)\n";
  std::cout << evaluation.Report();

  nlohmann::json json = {{"bench", "engine"},
                         {"frames", frames.size()},
                         {"registered", model.NumRegisteredImages()},
                         {"mean_reprojection_error_px", model.MeanReprojectionError()},
                         {"median_ms", Median(call_ms)},
                         {"stage_ms", stages},
                         {"median_ms_50_150", mid},
                         {"median_ms_last_100", last},
                         {"ate_rmse_m", evaluation.ate ? evaluation.ate->rmse : -1.0}};
  std::cout << json.dump() << "\n";
  return 0;
}
