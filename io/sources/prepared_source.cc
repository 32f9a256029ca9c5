#include "io/sources/prepared_source.h"

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

}  // namespace flysfm
