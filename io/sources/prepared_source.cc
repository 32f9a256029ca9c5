#include "io/sources/prepared_source.h"

#include <cmath>

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

std::optional<PreparedFrame> PreparedFrameSource::Next() {
  if (exhausted_) return std::nullopt;
  std::optional<PreparedFrame> prepared = next_.get();
  if (prepared) {
    next_ = std::async(std::launch::async, [this] { return FetchAndPrepare(); });
  } else {
    exhausted_ = true;
  }
  return prepared;
}

bool PreparedFrameSource::WaitReady(std::chrono::milliseconds timeout) const {
  return exhausted_ || next_.wait_for(timeout) == std::future_status::ready;
}

void RefineUntilNextFrame(Engine* engine, const PreparedFrameSource& source, double share,
                          const std::function<void(Engine::RefinementSlice*)>& on_slice) {
  const auto frame_ready = [&source] { return source.WaitReady(); };
  while (!frame_ready()) {
    const auto start = std::chrono::steady_clock::now();
    Engine::RefinementSlice slice = engine->Refine(frame_ready);
    if (slice.step == Engine::RefinementSlice::Step::kNone) return;
    on_slice(&slice);
    const std::chrono::duration<double> worked = std::chrono::steady_clock::now() - start;
    const double rest_s = worked.count() * (1 / share - 1);
    if (rest_s > 0) source.WaitReady(std::chrono::milliseconds(std::llround(1000 * rest_s)));
  }
}

}  // namespace flysfm
