#pragma once

// Runs the ingest side one image ahead: while the engine works on an image,
// the next one is fetched from the source, decoded and its features extracted
// on another thread (ARCHITECTURE.md: the loop itself stays single-threaded
// and deterministic; only Engine::Prepare, which needs no model, runs ahead).

#include <future>
#include <optional>

#include "core/engine.h"
#include "io/sources/image_source.h"

namespace flysfm {

class PreparedFrameSource {
 public:
  // `source` must outlive this object. `options`: the engine's (its SIFT
  // settings). Sets OpenCV to one thread for the process (cv::setNumThreads).
  PreparedFrameSource(ImageSource* source, Engine::Options options);
  // Stops the source (ImageSource::Stop), so that a source waiting for the
  // next shot lets the frame being fetched end, then waits for it: an
  // error that ends the engine loop early never hangs on the prefetch.
  ~PreparedFrameSource();

  // The next prepared frame, blocking until the source yields one; nullopt
  // once it is exhausted. Starts preparing the one after before returning.
  // An exception while preparing a frame makes it a frame with `error` set
  // (the engine's counted rejection); one from the source is rethrown.
  std::optional<PreparedFrame> Next();

 private:
  std::optional<PreparedFrame> FetchAndPrepare();

  ImageSource* source_;
  Engine::Options options_;
  std::future<std::optional<PreparedFrame>> next_;
  bool exhausted_ = false;
};

}  // namespace flysfm
