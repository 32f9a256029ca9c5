#pragma once

// What every engine benchmark shares: a session fed through the run loop
// (io/run/run_loop.h) exactly as `flysfm batch` feeds it, and the figures
// each benchmark reports from it in the same way: per-image time with every
// stage included, each stage's median, the growth over the session, the
// end's time, peak resident memory and page faults.

#include <functional>
#include <optional>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include "core/engine.h"
#include "io/run/run_loop.h"
#include "io/sources/image_source.h"

namespace flysfm::bench {

// The real data folder: $FLYSFM_DATA, else the one CMake was configured with.
std::string DefaultDataDir();
// `--data DIR` on `app`, defaulting to DefaultDataDir().
void AddDataOption(CLI::App* app, std::string* data);

// Whole process, in MB, from /proc/self/status ("VmRSS", "VmHWM"); -1 when
// it cannot be read.
double ProcStatusMb(const std::string& field);
// Resets VmHWM to the current RSS (Linux >= 4.0), so that the peak reported
// is the session's and not what ran before it (rendering).
bool ResetPeakRss();

struct SessionOptions {
  RunLoop::Options run;
  RunLoop::Hooks hooks;
  // Seconds between arrivals (FrameListSource); 0: all at once.
  double interval_s = 0;
  // After each engine call on a new image: its results, the sum of their
  // stage times, the call's wall time.
  std::function<void(const Engine&, const std::vector<ImageResult>&, const StageTimes&,
                     double engine_ms)>
      on_image;
};

// One session's figures.
struct Session {
  RunLoop::Summary run;
  // Per engine call on a new image: the sum of its results' stage times
  // (decode and features included, wherever they ran), the call's wall time
  // (the engine's own: decode and features ran ahead), and the pairs.
  std::vector<StageTimes> call_times;
  std::vector<double> all_stages_ms;
  std::vector<double> engine_ms;
  std::vector<int> verified_pairs;
  std::vector<int> candidates;
  // The last focal length the initial pairs' F put in place of the guess.
  std::optional<double> focal_length_from_pairs;
  double peak_rss_mb = 0;  // VmHWM at the end (reset at the start where Linux lets us)
  bool peak_reset = false;
  long page_faults = 0;    // minor faults of the process during the session
};

// Feeds `frames` to `engine` through the run loop (prints nothing unless
// options.run.print).
Session RunSession(Engine* engine, std::vector<Frame> frames, const SessionOptions& options);
// The same with a source of the caller's (several photographers merged:
// io/sources/merged_source.h); options.interval_s is the source's to apply.
Session RunSession(Engine* engine, ImageSource* source, const SessionOptions& options);

// Sum of `results`' stage times, `total` updated.
StageTimes SumOfTimes(const std::vector<ImageResult>& results);
// {"median", "p95", "max"} of `values`.
nlohmann::json Stats(const std::vector<double>& values);
// Each stage's median over calls [begin, end).
nlohmann::json StageMedians(const std::vector<StageTimes>& call_times, std::size_t begin,
                            std::size_t end);
// Median of values[begin, end), the bounds clamped.
double MedianOf(const std::vector<double>& values, std::size_t begin, std::size_t end);
// How per-image time grows over a session: the median of the last `window`
// values over the median of `window` values starting at `early_begin`
// (0 when either is empty).
double Growth(const std::vector<double>& values, std::size_t early_begin, std::size_t window);

// The session's figures as every engine benchmark prints and writes them.
void PrintSessionFigures(const Session& session, const char* label);
nlohmann::json SessionJson(const Session& session);

}  // namespace flysfm::bench
