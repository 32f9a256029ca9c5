#pragma once

// What a long step is doing, told to a person: the end of a run takes
// seconds to minutes (refinement's last pairs, the global adjustment, the
// data snooping, the final outputs), and a silent terminal cannot be told
// from a hang. On a terminal one line updates in place; elsewhere (a log
// file, a pipe) each state is a plain line of its own, at most one every
// `plain_interval_s` within one step, so that the output stays short and
// every line can be read by a script:
//   end: <step>[, <detail>]; <elapsed> s[, at most <remaining> s left]

#include <chrono>
#include <cstdio>
#include <optional>
#include <string>

namespace flysfm {

class ProgressLine {
 public:
  // `out` must outlive this object. Whether it is a terminal is asked once.
  explicit ProgressLine(std::FILE* out, double plain_interval_s = 5.0);
  // Ends an updating line with its newline.
  ~ProgressLine();
  ProgressLine(const ProgressLine&) = delete;
  ProgressLine& operator=(const ProgressLine&) = delete;

  // `step` names what runs now ("global adjustment"), `detail` how far it
  // is ("iteration 3 of at most 50"); a new step is always shown, the same
  // step again once the interval passed. `elapsed_s`: as the caller counts
  // (the end's time so far); `remaining_s`, when known, the most the step
  // may still take.
  void Show(const std::string& step, const std::string& detail, double elapsed_s,
            std::optional<double> remaining_s = std::nullopt);
  // Ends the current line: the next Show starts a new one.
  void Done();

  // The text Show prints for these figures (without "\r" or "\n").
  static std::string Format(const std::string& step, const std::string& detail,
                            double elapsed_s, std::optional<double> remaining_s);

 private:
  std::FILE* out_;
  bool terminal_;
  double plain_interval_s_;
  std::string last_step_;
  std::chrono::steady_clock::time_point last_shown_;
  bool line_open_ = false;
};

}  // namespace flysfm
