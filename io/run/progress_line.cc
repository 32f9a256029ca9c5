#include "io/run/progress_line.h"

#include <unistd.h>

#include <algorithm>
#include <cmath>

namespace flysfm {

ProgressLine::ProgressLine(std::FILE* out, double plain_interval_s)
    : out_(out), terminal_(::isatty(::fileno(out)) == 1), plain_interval_s_(plain_interval_s) {}

ProgressLine::~ProgressLine() { Done(); }

std::string ProgressLine::Format(const std::string& step, const std::string& detail,
                                 double elapsed_s, std::optional<double> remaining_s) {
  char text[64];
  if (remaining_s && std::isfinite(*remaining_s)) {
    std::snprintf(text, sizeof(text), "; %.1f s, at most %.0f s left", elapsed_s,
                  std::max(0.0, std::ceil(*remaining_s)));
  } else {
    std::snprintf(text, sizeof(text), "; %.1f s", elapsed_s);
  }
  return "end: " + step + (detail.empty() ? "" : ", " + detail) + text;
}

void ProgressLine::Show(const std::string& step, const std::string& detail, double elapsed_s,
                        std::optional<double> remaining_s) {
  const auto now = std::chrono::steady_clock::now();
  // A terminal redraws at most ten times a second; plain output repeats a
  // step only after the interval.
  const double interval_s = terminal_ ? 0.1 : plain_interval_s_;
  if (step == last_step_ &&
      std::chrono::duration<double>(now - last_shown_).count() < interval_s) {
    return;
  }
  const std::string text = Format(step, detail, elapsed_s, remaining_s);
  if (terminal_) {
    // \r and "erase to the end of the line": the line is rewritten in place.
    std::fprintf(out_, "\r%s\033[K", text.c_str());
    line_open_ = true;
  } else {
    std::fprintf(out_, "%s\n", text.c_str());
  }
  std::fflush(out_);
  last_step_ = step;
  last_shown_ = now;
}

void ProgressLine::Done() {
  if (line_open_) {
    std::fputc('\n', out_);
    std::fflush(out_);
  }
  line_open_ = false;
  last_step_.clear();
}

}  // namespace flysfm
