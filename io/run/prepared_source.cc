#include "io/run/prepared_source.h"

#include <algorithm>
#include <cmath>
#include <vector>

#include <opencv2/core/utility.hpp>

#include "geometry/statistics.h"

namespace flysfm {

PreparedFrameSource::PreparedFrameSource(ImageSource* source, Engine::Options options)
    : source_(source), options_(std::move(options)) {
  // SIFT gets the second core, the engine keeps the first: OpenCV's own
  // thread pool would spread SIFT over both and slow the engine down (fr1_xyz:
  // engine 301 -> 266 ms per frame, SIFT no slower on its one core).
  cv::setNumThreads(1);
  next_ = std::async(std::launch::async, [this] { return FetchAndPrepare(); });
}

PreparedFrameSource::~PreparedFrameSource() {
  source_->Stop();
  if (next_.valid()) next_.wait();
}

std::optional<PreparedFrame> PreparedFrameSource::FetchAndPrepare() {
  std::optional<Frame> frame = source_->Next();
  arrived_ = true;
  if (!frame) return std::nullopt;
  // Decoding and SIFT see the bytes from outside first: a failure there
  // (an allocation, an OpenCV assertion) is this image's, not the run's.
  std::string error;
  try {
    return Engine::Prepare(*frame, options_);
  } catch (const std::exception& e) {
    error = e.what();
  } catch (...) {
    error = "unknown exception";
  }
  PreparedFrame failed;
  failed.frame = std::move(*frame);
  failed.frame.bytes = {};
  failed.error = "preparing the image failed: " + error;
  return failed;
}

namespace {

// A cadence follows the photographer's latest rhythm, not the session's.
constexpr std::size_t kCadenceFrames = 9;


}  // namespace

std::optional<PreparedFrame> PreparedFrameSource::Next() {
  if (exhausted_) return std::nullopt;
  std::optional<PreparedFrame> prepared = next_.get();
  if (prepared) {
    arrived_ = false;
    next_ = std::async(std::launch::async, [this] { return FetchAndPrepare(); });
    if (prepared->frame.arrival != std::chrono::steady_clock::time_point()) {
      arrivals_.push_back(prepared->frame.arrival);
      if (arrivals_.size() > kCadenceFrames) arrivals_.pop_front();
    }
  } else {
    exhausted_ = true;
  }
  return prepared;
}

bool PreparedFrameSource::WaitReady(std::chrono::milliseconds timeout) const {
  return exhausted_ || next_.wait_for(timeout) == std::future_status::ready;
}

std::optional<PreparedFrameSource::Cadence> PreparedFrameSource::ShotCadence() const {
  if (arrivals_.size() < 3) return std::nullopt;
  std::vector<double> intervals_s;
  for (std::size_t i = 1; i < arrivals_.size(); ++i) {
    intervals_s.push_back(std::chrono::duration<double>(arrivals_[i] - arrivals_[i - 1]).count());
  }
  Cadence cadence;
  cadence.interval = std::chrono::duration_cast<std::chrono::steady_clock::duration>(
      std::chrono::duration<double>(Median(std::move(intervals_s))));
  cadence.next_arrival = arrivals_.back() + cadence.interval;
  return cadence;
}

void RefineUntilNextFrame(Engine* engine, const PreparedFrameSource& source, double share,
                          const std::function<void(Engine::RefinementSlice*)>& on_slice) {
  using Clock = std::chrono::steady_clock;
  const std::optional<PreparedFrameSource::Cadence> cadence = source.ShotCadence();
  // Engine::Refine polls `should_yield` between its units of work: the time
  // between two polls is the unit just done.
  Clock::duration longest_unit{0};
  Clock::time_point last_poll;
  const Clock::time_point rest_until =
      cadence ? cadence->next_arrival + cadence->interval / 2 : Clock::time_point();
  const auto no_time_left = [&](Clock::time_point now) {
    return cadence && now < rest_until && now + longest_unit > cadence->next_arrival;
  };
  const auto should_yield = [&] {
    const Clock::time_point now = Clock::now();
    longest_unit = std::max(longest_unit, now - last_poll);
    last_poll = now;
    return source.Arrived() || no_time_left(now);
  };
  // The prefetch signals a prepared frame, not an arrived one: resting polls
  // for the arrival, which costs the frame nothing (nothing runs meanwhile).
  const auto rest = [&](Clock::duration duration) {
    const Clock::time_point until = Clock::now() + duration;
    while (!source.Arrived() && Clock::now() < until) {
      source.WaitReady(std::chrono::milliseconds(5));
    }
  };
  while (!source.Arrived()) {
    const Clock::time_point start = Clock::now();
    if (no_time_left(start)) {
      rest(rest_until - start);
      continue;
    }
    last_poll = start;
    Engine::RefinementSlice slice = engine->Refine(should_yield);
    if (slice.step == Engine::RefinementSlice::Step::kNone) return;
    on_slice(&slice);
    const std::chrono::duration<double> worked = Clock::now() - start;
    rest(std::chrono::duration_cast<Clock::duration>(worked * (1 / share - 1)));
  }
}

}  // namespace flysfm
