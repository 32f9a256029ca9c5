// What a checkpoint costs and what it saves. A child process runs the first
// N images of a folder (or TUM sequence) through the run loop with an output
// folder, as `flysfm batch` and `live` do (its checkpoint written after each
// image), and kills itself with SIGKILL right after the N-th, as a power
// cut or the OOM killer would: no final checkpoint. Then a restart in this
// process resumes from the folder, as running the same command again does,
// and processes image N+1. Prints the checkpoint's cost per image against
// the engine's time, the checkpoint folder's size per image, the time from
// the restart to the first new result (restore, the images after the last
// snapshot fed again, then the new image's decoding, features and engine
// work), and, as the baseline measured in the same run, what replaying the
// N images would cost instead. Ends with one line of JSON.
//
//   bench_resume INPUT [--images N] [--camera "MODEL p1,..."]
//
// e.g. 300 VGA frames of TUM fr1_xyz, and 100 photos of 6 MP rendered by
// bench_photos (docs/benchmarks.md).

#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <numeric>
#include <optional>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include "bench/bench_session.h"
#include "core/engine.h"
#include "core/malloc_policy.h"
#include "geometry/statistics.h"
#include "io/sources/image_source.h"

namespace flysfm {
namespace {

namespace fs = std::filesystem;

std::uintmax_t FolderBytes(const fs::path& dir) {
  std::uintmax_t bytes = 0;
  for (const auto& entry : fs::recursive_directory_iterator(dir)) {
    if (entry.is_regular_file()) bytes += entry.file_size();
  }
  return bytes;
}

Engine MakeEngine(const std::string& camera_text) {
  std::optional<Camera> camera;
  if (!camera_text.empty()) camera = Camera::FromString(camera_text, 0, 0);
  return Engine(Engine::Options(), camera);
}

RunLoop::Options LoopOptions(const fs::path& out, bool resume) {
  RunLoop::Options options;
  options.print = false;
  options.out = out.string();
  options.resume = resume;
  options.between_images = RunLoop::Options::BetweenImages::kNothing;
  return options;
}

// The child: the session through the run loop, killed once its last image
// is checkpointed. Each engine call's and checkpoint's times go to `times`.
[[noreturn]] void RunAndDie(std::vector<Frame> frames, const std::string& camera_text,
                            const fs::path& out, const fs::path& times) {
  Engine engine = MakeEngine(camera_text);
  const std::size_t num_images = frames.size();
  std::ofstream log(times);
  std::size_t done = 0;
  std::chrono::steady_clock::time_point call_end;
  RunLoop::Hooks hooks;
  hooks.on_image = [&](const Engine&, const std::vector<ImageResult>&, double call_ms) {
    log << call_ms << " ";
    call_end = std::chrono::steady_clock::now();
  };
  // From the engine call's end to here: the log line, the checkpoint and,
  // when due, the model files: what the outputs cost each image.
  hooks.after_image = [&](const Engine&) {
    log << std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - call_end)
               .count()
        << "\n";
    if (++done % 50 == 0) {
      std::printf("[%4zu] checkpointed\n", done);
      std::fflush(stdout);
    }
    if (done < num_images) return;
    log.flush();
    ::raise(SIGKILL);
  };
  FrameListSource source(std::move(frames));
  RunLoop(LoopOptions(out, false)).Run(&source, &engine, hooks);
  std::abort();  // the last image's hook kills the process first
}

// Per image: the engine call's time and the outputs' after it.
void ReadTimes(const fs::path& file, std::vector<double>* engine_ms,
               std::vector<double>* outputs_ms) {
  std::ifstream in(file);
  for (double engine, outputs; in >> engine >> outputs;) {
    engine_ms->push_back(engine);
    outputs_ms->push_back(outputs);
  }
}

int Main(const std::string& input, int num_images, const std::string& camera_text) {
  std::vector<Frame> frames = ListBatchInput(input);
  if (int(frames.size()) < num_images + 1) {
    std::cerr << "bench_resume: " << input << " has " << frames.size() << " images; "
              << num_images + 1 << " are needed\n";
    return 2;
  }
  frames.resize(std::size_t(num_images) + 1);
  const fs::path work = fs::temp_directory_path() / ("bench_resume_" + std::to_string(::getpid()));
  const fs::path out = work / "out";
  fs::create_directories(work);

  // Forked before this process starts a thread.
  const pid_t child = ::fork();
  if (child == 0) {
    RunAndDie(std::vector<Frame>(frames.begin(), frames.end() - 1), camera_text, out,
              work / "times.txt");
  }
  int status = 0;
  ::waitpid(child, &status, 0);
  if (!WIFSIGNALED(status) || WTERMSIG(status) != SIGKILL) {
    std::cerr << "bench_resume: the session did not end as killed (status " << status << ")\n";
    return 1;
  }
  std::vector<double> engine_ms, outputs_ms;
  ReadTimes(work / "times.txt", &engine_ms, &outputs_ms);
  const std::uintmax_t state_bytes = FolderBytes(out / "state");

  // The restart: the same command again, with one more image.
  const auto restart = std::chrono::steady_clock::now();
  Engine engine = MakeEngine(camera_text);
  double first_result_s = 0;
  RunLoop::Hooks hooks;
  int fed = 0;
  hooks.on_image = [&](const Engine&, const std::vector<ImageResult>& results, double) {
    ++fed;
    if (results.front().name == frames.back().name) {
      first_result_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - restart)
                           .count();
    }
  };
  FrameListSource source(frames);
  const RunLoop::Summary resumed = RunLoop(LoopOptions(out, true)).Run(&source, &engine, hooks);
  fs::remove_all(work);

  const double engine_total = std::accumulate(engine_ms.begin(), engine_ms.end(), 0.0);
  const double outputs_total = std::accumulate(outputs_ms.begin(), outputs_ms.end(), 0.0);
  // A replay redoes every image's engine work (decoding and features
  // overlapped on the other core: the engine's time bounds it).
  const double replay_s = engine_total / 1000;
  std::printf("\n%d images of %s, %d resumed, %zu registered at the end\n", num_images,
              input.c_str(), resumed.counts.resumed_images,
              engine.reconstruction().NumRegisteredImages());
  std::printf("checkpoint folder after %d images: %.1f MB, %.0f KB per image\n", num_images,
              state_bytes / 1e6, state_bytes / 1e3 / num_images);
  std::printf("outputs per image (log, checkpoint, model files when due): median %.1f ms, "
              "%.2f %% of the engine's time\n",
              Median(outputs_ms), 100 * outputs_total / engine_total);
  std::printf("restart: %d images fed again after the last snapshot, then the new one; first "
              "new result %.2f s after the restart; a replay would take %.1f s (ratio %.3f); "
              "engine median %.0f ms per image\n",
              fed - 1, first_result_s, replay_s, first_result_s / replay_s, Median(engine_ms));
  const nlohmann::json json = {{"bench", "resume"},
                               {"input", input},
                               {"images", num_images},
                               {"resumed_images", resumed.counts.resumed_images},
                               {"engine_median_ms", Median(engine_ms)},
                               {"outputs_median_ms", Median(outputs_ms)},
                               {"outputs_share", outputs_total / engine_total},
                               {"state_bytes", state_bytes},
                               {"state_bytes_per_image", double(state_bytes) / num_images},
                               {"fed_again", fed - 1},
                               {"restart_to_first_result_s", first_result_s},
                               {"replay_s", replay_s},
                               {"restart_over_replay", first_result_s / replay_s}};
  std::cout << json.dump() << "\n";
  return 0;
}

}  // namespace
}  // namespace flysfm

int main(int argc, char** argv) {
  using namespace flysfm;
  ApplyMallocPolicy();  // as flysfm does: the engine measured as it runs there
  CLI::App app("What a checkpoint costs and what a restart after SIGKILL saves");
  std::string input;
  int num_images = 300;
  std::string camera;
  app.add_option("input", input, "Image folder or TUM sequence folder")->required();
  app.add_option("--images", num_images, "Images before the kill")
      ->check(CLI::Range(2, 1000000))
      ->capture_default_str();
  app.add_option("--camera", camera, "Known intrinsics, \"MODEL p1,p2,...\"");
  CLI11_PARSE(app, argc, argv);
  return Main(input, num_images, camera);
}
