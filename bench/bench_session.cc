#include "bench/bench_session.h"

#include <sys/resource.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <fstream>

#include "geometry/statistics.h"

namespace flysfm::bench {

std::string DefaultDataDir() {
  const char* data = std::getenv("FLYSFM_DATA");
  return data != nullptr ? data : FLYSFM_DEFAULT_DATA_DIR;
}

void AddDataOption(CLI::App* app, std::string* data) {
  *data = DefaultDataDir();
  app->add_option("--data", *data, "Real data folder (default: $FLYSFM_DATA or the configured one)")
      ->capture_default_str();
}

double ProcStatusMb(const std::string& field) {
  std::ifstream status("/proc/self/status");
  for (std::string line; std::getline(status, line);) {
    if (line.compare(0, field.size() + 1, field + ":") == 0) {
      return std::atof(line.c_str() + field.size() + 1) / 1024.0;
    }
  }
  return -1;
}

bool ResetPeakRss() {
  std::ofstream clear("/proc/self/clear_refs");
  clear << "5";
  return bool(clear.flush());
}

StageTimes SumOfTimes(const std::vector<ImageResult>& results) {
  StageTimes sum;
  for (const ImageResult& result : results) {
    for (const auto& [name, stage] : StageTimes::Stages()) sum.*stage += result.times.*stage;
  }
  sum.UpdateTotal();
  return sum;
}

Session RunSession(Engine* engine, std::vector<Frame> frames, const SessionOptions& options) {
  FrameListSource source(std::move(frames), options.interval_s);
  return RunSession(engine, &source, options);
}

Session RunSession(Engine* engine, ImageSource* source, const SessionOptions& options) {
  Session session;
  session.peak_reset = ResetPeakRss();
  rusage usage;
  getrusage(RUSAGE_SELF, &usage);
  session.page_faults = -usage.ru_minflt;
  RunLoop::Hooks hooks = options.hooks;
  hooks.on_image = [&](const Engine& engine, const std::vector<ImageResult>& results,
                       double call_ms) {
    const StageTimes times = SumOfTimes(results);
    session.call_times.push_back(times);
    session.all_stages_ms.push_back(times.total);
    session.engine_ms.push_back(call_ms);
    session.verified_pairs.push_back(results.front().num_verified_pairs);
    session.candidates.push_back(results.front().num_candidates);
    for (const ImageResult& result : results) {
      if (result.focal_length_from_pairs) {
        session.focal_length_from_pairs = result.focal_length_from_pairs;
      }
    }
    if (options.hooks.on_image) options.hooks.on_image(engine, results, call_ms);
    if (options.on_image) options.on_image(engine, results, times, call_ms);
  };
  session.run = RunLoop(options.run).Run(source, engine, hooks);
  session.peak_rss_mb = ProcStatusMb("VmHWM");
  getrusage(RUSAGE_SELF, &usage);
  session.page_faults += usage.ru_minflt;
  return session;
}

nlohmann::json Stats(const std::vector<double>& values) {
  return nlohmann::json{{"median", Median(values)},
                        {"p95", Quantile(values, 0.95)},
                        {"max", values.empty() ? 0.0
                                               : *std::max_element(values.begin(), values.end())}};
}

double MedianOf(const std::vector<double>& values, std::size_t begin, std::size_t end) {
  end = std::min(end, values.size());
  begin = std::min(begin, end);
  return Median(std::vector<double>(values.begin() + std::ptrdiff_t(begin),
                                    values.begin() + std::ptrdiff_t(end)));
}

nlohmann::json StageMedians(const std::vector<StageTimes>& call_times, std::size_t begin,
                            std::size_t end) {
  end = std::min(end, call_times.size());
  begin = std::min(begin, end);
  nlohmann::json stages;
  for (const auto& [name, stage] : StageTimes::Stages()) {
    std::vector<double> values;
    for (std::size_t i = begin; i < end; ++i) values.push_back(call_times[i].*stage);
    stages[name] = Median(values);
  }
  return stages;
}

double Growth(const std::vector<double>& values, std::size_t early_begin, std::size_t window) {
  const std::size_t n = values.size();
  const double early = MedianOf(values, early_begin, early_begin + window);
  const double late = MedianOf(values, n >= window ? n - window : 0, n);
  return early > 0 && late > 0 ? late / early : 0;
}

void PrintSessionFigures(const Session& session, const char* label) {
  const nlohmann::json all = Stats(session.all_stages_ms);
  const nlohmann::json engine = Stats(session.engine_ms);
  std::printf("%s: per-image time, all stages: median %.0f ms, p95 %.0f ms, max %.0f ms; "
              "engine call (decode and features ran ahead): median %.0f ms, p95 %.0f ms\n",
              label, all["median"].get<double>(), all["p95"].get<double>(),
              all["max"].get<double>(), engine["median"].get<double>(),
              engine["p95"].get<double>());
  std::printf("%s: stage medians (ms):", label);
  const nlohmann::json stages = StageMedians(session.call_times, 0, session.call_times.size());
  for (const auto& [name, stage] : StageTimes::Stages()) {
    std::printf(" %s %.0f", name, stages[name].get<double>());
  }
  const RunLoop::Summary& run = session.run;
  std::printf("\n%s: %.1f s in all, the last image's result at %.1f s, the end (refinement "
              "left, Finish, final outputs) %.1f s = %.1f %% of the run (Finish %.1f s); peak "
              "RSS %.0f MB%s; %ld page faults\n",
              label, run.wall_s, run.last_image_s, run.end_s,
              run.wall_s > 0 ? 100 * run.end_s / run.wall_s : 0.0, run.finish_s,
              session.peak_rss_mb, session.peak_reset ? "" : " (not reset: whole process)",
              session.page_faults);
  std::fflush(stdout);
}

nlohmann::json SessionJson(const Session& session) {
  const RunLoop::Summary& run = session.run;
  return {{"all_stages_ms", Stats(session.all_stages_ms)},
          {"engine_ms", Stats(session.engine_ms)},
          {"stage_median_ms", StageMedians(session.call_times, 0, session.call_times.size())},
          {"wall_s", run.wall_s},
          {"last_image_s", run.last_image_s},
          {"end_s", run.end_s},
          {"end_share", run.wall_s > 0 ? run.end_s / run.wall_s : 0.0},
          {"finish_s", run.finish_s},
          {"peak_rss_mb", session.peak_rss_mb},
          {"page_faults", session.page_faults}};
}

}  // namespace flysfm::bench
