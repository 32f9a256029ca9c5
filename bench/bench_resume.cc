// What a checkpoint costs and what it saves: the engine runs on the first N
// images of a folder (or TUM sequence) with its checkpoint written after
// each image, as `flysfm batch` and `live` do; then a restart restores it
// and processes image N+1. Prints the checkpoint's cost per image against
// the engine's time, the time from the restart to the first new result
// (restore, the images after the last snapshot fed again, then the new
// image's decoding, features and engine work), and,
// as the baseline measured in the same run, what replaying the N images
// would cost instead. Ends with one line of JSON.
//
//   bench_resume INPUT [--images N] [--camera "MODEL p1,..."]
//
// e.g. 300 VGA frames of TUM fr1_xyz, and 100 photos of 6 MP rendered by
// bench_photos (docs/benchmarks.md).

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <iostream>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include <unistd.h>

#include <nlohmann/json.hpp>

#include "core/engine.h"
#include "core/malloc_policy.h"
#include "io/run/checkpoint.h"
#include "io/sources/image_source.h"
#include "io/sources/prepared_source.h"

namespace {

using Clock = std::chrono::steady_clock;

double MsSince(Clock::time_point start) {
  return std::chrono::duration<double, std::milli>(Clock::now() - start).count();
}

double Median(std::vector<double> values) {
  if (values.empty()) return 0;
  std::nth_element(values.begin(), values.begin() + values.size() / 2, values.end());
  return values[values.size() / 2];
}

}  // namespace

int main(int argc, char** argv) {
  using namespace flysfm;
  ApplyMallocPolicy();  // as flysfm does: the engine measured as it runs there
  std::string input;
  int num_images = 300;
  std::string camera_text;
  for (int i = 1; i < argc; ++i) {
    const bool has_value = i + 1 < argc;
    if (!std::strcmp(argv[i], "--images") && has_value) {
      num_images = std::atoi(argv[++i]);
    } else if (!std::strcmp(argv[i], "--camera") && has_value) {
      camera_text = argv[++i];
    } else if (input.empty() && argv[i][0] != '-') {
      input = argv[i];
    } else {
      input.clear();
      break;
    }
  }
  if (input.empty() || num_images < 2) {
    std::cerr << "usage: bench_resume INPUT [--images N>=2] [--camera \"MODEL p1,...\"]\n";
    return 2;
  }
  std::vector<Frame> frames = ListBatchInput(input);
  if (int(frames.size()) < num_images + 1) {
    std::cerr << "bench_resume: " << input << " has " << frames.size() << " images; "
              << num_images + 1 << " are needed\n";
    return 2;
  }
  frames.resize(std::size_t(num_images) + 1);
  std::optional<Camera> camera;
  if (!camera_text.empty()) camera = Camera::FromString(camera_text, 0, 0);
  const Engine::Options options;
  namespace fs = std::filesystem;
  const fs::path state = fs::temp_directory_path() /
                         ("bench_resume_" + std::to_string(::getpid())) / "state";

  // The session, checkpointed image by image.
  std::vector<double> engine_ms, checkpoint_ms;
  Checkpointer::Summary summary;
  std::size_t registered = 0;
  {
    Engine engine(options, camera);
    Checkpointer checkpointer(state, Checkpointer::Options());
    checkpointer.Clear();
    FrameListSource source(std::vector<Frame>(frames.begin(), frames.end() - 1));
    PreparedFrameSource prepared(&source, options);
    while (std::optional<PreparedFrame> frame = prepared.Next()) {
      auto start = Clock::now();
      engine.AddImage(std::move(*frame));
      engine_ms.push_back(MsSince(start));
      start = Clock::now();
      checkpointer.Update(engine, engine_ms.back());
      checkpoint_ms.push_back(MsSince(start));
      if (engine_ms.size() % 50 == 0) {
        std::printf("[%4zu] engine %5.0f ms, checkpoint %5.1f ms; %d snapshots so far, last "
                    "%.0f ms for %.1f MB\n",
                    engine_ms.size(), engine_ms.back(), checkpoint_ms.back(),
                    checkpointer.summary().num_snapshots, checkpointer.summary().last_snapshot_ms,
                    checkpointer.summary().last_snapshot_bytes / 1e6);
        std::fflush(stdout);
      }
    }
    summary = checkpointer.summary();
    registered = engine.reconstruction().NumRegisteredImages();
  }

  // The restart, as RunEngine does it: restore, feed again the images that
  // came after the last snapshot, then the next image, as a new shot would
  // come.
  const auto restart = Clock::now();
  Engine engine(options, camera);
  Checkpointer checkpointer(state, Checkpointer::Options());
  checkpointer.Restore(&engine);
  const double restore_ms = MsSince(restart);
  const std::size_t restored = engine.reconstruction().images().size();
  std::set<std::string> in_model;
  for (const auto& [image_id, image] : engine.reconstruction().images()) in_model.insert(image.name);
  int replayed = 0;
  for (auto frame = frames.begin(); frame + 1 != frames.end(); ++frame) {
    if (in_model.count(frame->name) == 0) {
      engine.AddImage(*frame);
      ++replayed;
    }
  }
  const std::vector<ImageResult> next = engine.AddImage(frames.back());
  const double first_result_ms = MsSince(restart);
  fs::remove_all(state.parent_path());

  double engine_total = 0, checkpoint_total = 0;
  for (const double ms : engine_ms) engine_total += ms;
  for (const double ms : checkpoint_ms) checkpoint_total += ms;
  const double share = checkpoint_total / engine_total;
  // A replay redoes every image's engine work, and decodes and extracts
  // each again (on the other core, overlapped: the engine's time bounds it).
  const double replay_ms = engine_total;
  std::printf("\n%d images of %s, %zu registered\n", num_images, input.c_str(), registered);
  std::printf("checkpoint per image: median %.1f ms, mean %.1f ms; %.2f %% of the engine's "
              "time (engine median %.0f ms); %d snapshots (last %.0f ms, %.1f MB), %.1f MB "
              "written in all\n",
              Median(checkpoint_ms), checkpoint_total / num_images, 100 * share,
              Median(engine_ms), summary.num_snapshots, summary.last_snapshot_ms,
              summary.last_snapshot_bytes / 1e6, summary.bytes / 1e6);
  std::printf("restart: restored %zu images in %.2f s, fed %d after the last snapshot again; "
              "first new result (%s, %s) %.2f s after the restart; a replay would take %.1f s "
              "(ratio %.3f)\n",
              restored, restore_ms / 1000, replayed, next.front().name.c_str(),
              ImageStatusName(next.front().status), first_result_ms / 1000, replay_ms / 1000,
              first_result_ms / replay_ms);
  const nlohmann::json json = {{"bench", "resume"},
                               {"input", input},
                               {"images", num_images},
                               {"registered", registered},
                               {"engine_median_ms", Median(engine_ms)},
                               {"checkpoint_median_ms", Median(checkpoint_ms)},
                               {"checkpoint_share", share},
                               {"snapshots", summary.num_snapshots},
                               {"last_snapshot_ms", summary.last_snapshot_ms},
                               {"last_snapshot_mb", summary.last_snapshot_bytes / 1e6},
                               {"written_mb", summary.bytes / 1e6},
                               {"restored_images", restored},
                               {"restore_s", restore_ms / 1000},
                               {"fed_again", replayed},
                               {"restart_to_first_result_s", first_result_ms / 1000},
                               {"replay_s", replay_ms / 1000},
                               {"restart_over_replay", first_result_ms / replay_ms}};
  std::cout << json.dump() << "\n";
  return 0;
}
