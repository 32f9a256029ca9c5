#include "io/sources/prepared_source.h"

#include <algorithm>
#include <cmath>
#include <vector>

#include <opencv2/core/utility.hpp>

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

template <typename T>
T Median(std::vector<T> values) {
  std::nth_element(values.begin(), values.begin() + values.size() / 2, values.end());
  return values[values.size() / 2];
}

}  // namespace

std::optional<PreparedFrame> PreparedFrameSource::Next() {
  if (exhausted_) return std::nullopt;
  std::optional<PreparedFrame> prepared = next_.get();
  if (prepared) {
    next_ = std::async(std::launch::async, [this] { return FetchAndPrepare(); });
    if (prepared->frame.arrival != std::chrono::steady_clock::time_point()) {
      shots_.push_back({prepared->frame.arrival,
                        std::chrono::duration<double>(
                            (prepared->decode_ms + prepared->features_ms) / 1000)});
      if (shots_.size() > kCadenceFrames) shots_.pop_front();
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
  if (shots_.size() < 3) return std::nullopt;
  std::vector<std::chrono::steady_clock::duration> intervals;
  std::vector<std::chrono::duration<double>> prepares = {shots_.front().prepare};
  for (std::size_t i = 1; i < shots_.size(); ++i) {
    intervals.push_back(shots_[i].arrival - shots_[i - 1].arrival);
    prepares.push_back(shots_[i].prepare);
  }
  Cadence cadence;
  cadence.interval = Median(std::move(intervals));
  cadence.next_ready =
      shots_.back().arrival + cadence.interval +
      std::chrono::duration_cast<std::chrono::steady_clock::duration>(Median(std::move(prepares)));
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
      cadence ? cadence->next_ready + cadence->interval / 2 : Clock::time_point();
  const auto no_time_left = [&](Clock::time_point now) {
    return cadence && now < rest_until && now + longest_unit > cadence->next_ready;
  };
  const auto should_yield = [&] {
    const Clock::time_point now = Clock::now();
    longest_unit = std::max(longest_unit, now - last_poll);
    last_poll = now;
    return source.WaitReady() || no_time_left(now);
  };
  while (!source.WaitReady()) {
    const Clock::time_point start = Clock::now();
    if (no_time_left(start)) {
      source.WaitReady(std::chrono::ceil<std::chrono::milliseconds>(rest_until - start));
      continue;
    }
    last_poll = start;
    Engine::RefinementSlice slice = engine->Refine(should_yield);
    if (slice.step == Engine::RefinementSlice::Step::kNone) return;
    on_slice(&slice);
    const std::chrono::duration<double> worked = Clock::now() - start;
    const double rest_s = worked.count() * (1 / share - 1);
    if (rest_s > 0) source.WaitReady(std::chrono::milliseconds(std::llround(1000 * rest_s)));
  }
}

}  // namespace flysfm
