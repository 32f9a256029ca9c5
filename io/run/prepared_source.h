#pragma once

// Runs the ingest side one image ahead: while the engine works on an image,
// the next one is fetched from the source, decoded and its features extracted
// on another thread (the loop itself stays single-threaded
// and deterministic; only Engine::Prepare, which needs no model, runs ahead).

#include <atomic>
#include <chrono>
#include <deque>
#include <functional>
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
  // Whether Next() would return at once (the next frame is prepared, or the
  // source is exhausted), after waiting at most `timeout` for it.
  bool WaitReady(std::chrono::milliseconds timeout = std::chrono::milliseconds(0)) const;
  // Whether the next frame has come from the source (it may still be being
  // prepared), or the source is exhausted.
  bool Arrived() const { return arrived_.load(); }
  // The shots' recent rhythm: the median of the last intervals between
  // arrivals, and when the frame after those Next() returned should arrive
  // if the shots keep it (the last arrival plus that interval). nullopt
  // before three frames with an arrival time.
  struct Cadence {
    std::chrono::steady_clock::duration interval;
    std::chrono::steady_clock::time_point next_arrival;
  };
  std::optional<Cadence> ShotCadence() const;

 private:
  std::optional<PreparedFrame> FetchAndPrepare();

  ImageSource* source_;
  Engine::Options options_;
  std::future<std::optional<PreparedFrame>> next_;
  // Set by the prefetch once the source's Next() returned, cleared when the
  // prefetch of the frame after starts.
  std::atomic<bool> arrived_{false};
  bool exhausted_ = false;
  // When each of the last frames Next() returned arrived.
  std::deque<std::chrono::steady_clock::time_point> arrivals_;
};

// Refinement slices (Engine::Refine) until the next frame arrives, each
// ending as soon as it has: a new image waits for one unit of a slice at
// most (a pair, an image, a BA iteration), and is decoded and its features
// extracted with the machine to itself. On this 2-core machine a global BA
// beside SIFT made SIFT of a 6 MP photo 13 % slower (bench_refine, the
// rendered set: latency median 827 ms off, 899 ms on). And while the shots
// keep their cadence (PreparedFrameSource::ShotCadence), no unit starts that,
// as long as the longest one seen meanwhile, would end after the next frame
// is expected to arrive: it rests instead, up to half an interval past that
// time (a shot a little late is a shot; one later is a pause, which
// refinement gets the rest of). After a slice of t seconds it rests
// t (1/share - 1) seconds, or until a frame arrives: refinement takes at
// most `share` (0, 1] of the engine's core. `on_slice` sees each slice that
// did something. Returns when a frame has arrived or nothing is left to
// refine; an exception of the engine propagates.
void RefineUntilNextFrame(Engine* engine, const PreparedFrameSource& source, double share,
                          const std::function<void(Engine::RefinementSlice*)>& on_slice);

}  // namespace flysfm
