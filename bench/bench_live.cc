// Live capture end to end on one machine: the CAMFI emulator shoots the
// first TUM freiburg1_xyz frames (re-encoded as JPEG, as a camera writes
// them) at a fixed interval; the CAMFI client downloads each into a store
// and the engine processes it. Figure: the delay from the `file_added` event
// reaching the client to the image's result, which must stay below the
// interval (each image done before the next is shot). Ends with one line of
// JSON.
//
//   bench_live [--frames N] [--interval S] [--data DIR]

#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <iostream>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include "bench/bench_session.h"
#include "geometry/statistics.h"
#include "io/run/run_loop.h"

#include "core/engine.h"
#include "core/malloc_policy.h"
#include "io/camfi/camfi_client.h"
#include "io/camfi/camfi_emulator.h"
#include "io/sources/image_source.h"

int main(int argc, char** argv) {
  using namespace flysfm;
  ApplyMallocPolicy();  // as flysfm does: the engine measured as it runs there
  CLI::App app("Live capture from the CAMFI emulator, the delay from each shot to its result");
  int num_frames = 30;
  double interval = 1.0;
  std::string data;
  app.add_option("--frames", num_frames, "fr1_xyz frames shot")->capture_default_str();
  app.add_option("--interval", interval, "Seconds between shots")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  bench::AddDataOption(&app, &data);
  CLI11_PARSE(app, argc, argv);
  std::vector<Frame> frames;
  try {
    frames = ListTumSequence(data + "/tum/rgbd_dataset_freiburg1_xyz");
  } catch (const std::exception& e) {
    std::cerr << "bench_live: " << e.what() << " (set FLYSFM_DATA or --data)\n";
    return 2;
  }
  if (int(frames.size()) > num_frames) frames.resize(std::size_t(num_frames));

  CamfiEmulatorOptions emulator_options;
  for (const Frame& frame : frames) emulator_options.images.push_back(frame.path);
  emulator_options.http_port = 0;
  emulator_options.event_port = 0;
  emulator_options.interval_seconds = interval;
  CamfiEmulator emulator(emulator_options);

  const std::filesystem::path store =
      std::filesystem::temp_directory_path() / ("bench_live_" + std::to_string(::getpid()));
  std::filesystem::remove_all(store);
  CamfiOptions client_options;
  client_options.host = "127.0.0.1";
  client_options.http_port = emulator.http_port();
  client_options.event_port = emulator.event_port();
  Engine engine(Engine::Options(),
                Camera::FromString("FULL_OPENCV 517.3,516.5,318.6,255.3,0.2624,-0.9531,"
                                   "-0.0054,0.0026,1.1633,0,0,0",
                                   0, 0));
  std::vector<double> delays_ms;
  std::vector<double> engine_ms;
  int late = 0;
  {
    CamfiSource source(client_options, store);
    LimitedSource limited(&source, int(frames.size()));
    RunLoop::Options options;
    options.print = false;
    options.live = true;
    const RunLoop::Summary summary = RunLoop(options).Run(&limited, &engine);
    for (const RunLoop::Reported& reported : summary.results) {
      if (!reported.arriving_image || !reported.delay_ms) continue;
      const double delay = *reported.delay_ms;
      delays_ms.push_back(delay);
      engine_ms.push_back(reported.result.times.total);
      late += delay >= 1000 * interval;
      std::printf("%-44s %-10s engine %6.0f ms  delay file_added -> result %6.0f ms\n",
                  reported.result.name.c_str(), ImageStatusName(reported.result.status),
                  reported.result.times.total, delay);
    }
  }
  std::filesystem::remove_all(store);
  const double median_delay = Median(delays_ms);
  // The delay minus the engine's own time: download, store, journal, and
  // waiting while the engine still works on an earlier image.
  std::vector<double> transfer_ms;
  for (std::size_t i = 0; i < delays_ms.size(); ++i) {
    transfer_ms.push_back(delays_ms[i] - engine_ms[i]);
  }
  std::printf("\n%zu frames at %.2f s: median delay file_added -> result %.0f ms (%s the "
              "interval); %d of %zu at or over the interval; median engine time %.0f ms; "
              "median time before the engine (download, store, waiting) %.0f ms; %zu registered\n",
              delays_ms.size(), interval, median_delay,
              median_delay < 1000 * interval ? "below" : "NOT below", late, delays_ms.size(),
              Median(engine_ms), Median(transfer_ms),
              engine.reconstruction().NumRegisteredImages());
  const double max_delay =
      delays_ms.empty() ? 0.0 : *std::max_element(delays_ms.begin(), delays_ms.end());
  const nlohmann::json json = {{"bench", "live"},
                               {"frames", delays_ms.size()},
                               {"interval_s", interval},
                               {"median_delay_ms", median_delay},
                               {"max_delay_ms", max_delay},
                               {"late", late},
                               {"median_engine_ms", Median(engine_ms)},
                               {"median_before_engine_ms", Median(transfer_ms)},
                               {"registered", engine.reconstruction().NumRegisteredImages()}};
  std::cout << json.dump() << "\n";
  return 0;
}
