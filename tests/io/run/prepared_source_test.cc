#include "io/run/prepared_source.h"

#include <algorithm>
#include <chrono>
#include <condition_variable>
#include <mutex>
#include <thread>

#include <catch2/catch.hpp>

#include "io/synthetic/synthetic_source.h"
#include "tests/testing/rendered_capture.h"

namespace flysfm {
namespace {

TEST_CASE("Frames come prepared, in the source's order, as Engine::Prepare makes them") {
  SyntheticCaptureOptions capture_options;
  capture_options.num_views = 3;
  std::vector<Frame> frames = testing::RenderedCapture(capture_options).frames;
  Frame bad;
  bad.name = "truncated.png";
  bad.bytes = std::vector<std::uint8_t>(frames[0].bytes.begin(), frames[0].bytes.begin() + 100);
  frames.insert(frames.begin() + 1, bad);

  const Engine::Options options;
  FrameListSource source(frames);
  PreparedFrameSource prepared(&source, options);
  for (const Frame& frame : frames) {
    std::optional<PreparedFrame> next = prepared.Next();
    REQUIRE(next);
    CHECK(next->frame.name == frame.name);
    const PreparedFrame expected = Engine::Prepare(frame, options);
    CHECK(next->error == expected.error);
    CHECK(next->features.size() == expected.features.size());
    CHECK(next->features.descriptors == expected.features.descriptors);
  }
  CHECK_FALSE(prepared.Next());
  CHECK_FALSE(prepared.Next());
}

// A live source between shots: Next() waits until Stop() (or, so that a
// broken stop fails the test instead of hanging it, a few seconds).
class WaitingSource : public ImageSource {
 public:
  std::optional<Frame> Next() override {
    std::unique_lock<std::mutex> lock(mutex_);
    stopped_changed_.wait_for(lock, std::chrono::seconds(5), [this] { return stopped_; });
    return std::nullopt;
  }
  void Stop() override {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      stopped_ = true;
    }
    stopped_changed_.notify_all();
  }

 private:
  std::mutex mutex_;
  std::condition_variable stopped_changed_;
  bool stopped_ = false;
};

TEST_CASE("WaitReady tells whether the next frame is prepared, waiting at most as long as "
          "asked") {
  SyntheticCaptureOptions capture_options;
  capture_options.num_views = 2;
  // The second frame is due 3 s after the first: well after the first is
  // prepared, even under a sanitizer.
  FrameListSource source(testing::RenderedCapture(capture_options).frames, 3.0);
  PreparedFrameSource prepared(&source, Engine::Options());
  REQUIRE(prepared.WaitReady(std::chrono::seconds(5)));
  REQUIRE(prepared.Next());
  const auto start = std::chrono::steady_clock::now();
  CHECK_FALSE(prepared.WaitReady());
  CHECK_FALSE(prepared.WaitReady(std::chrono::milliseconds(100)));
  CHECK(std::chrono::steady_clock::now() - start < std::chrono::seconds(2));
  CHECK(prepared.WaitReady(std::chrono::seconds(5)));
  REQUIRE(prepared.Next());
  // The end of the list is ready at once, and stays so.
  CHECK(prepared.WaitReady(std::chrono::seconds(5)));
  CHECK_FALSE(prepared.Next());
  CHECK(prepared.WaitReady());
}

// Frames that arrived at given times, as a camera's shots did.
class StampedSource : public ImageSource {
 public:
  explicit StampedSource(std::vector<Frame> frames) : frames_(std::move(frames)) {}
  std::optional<Frame> Next() override {
    if (next_ == frames_.size()) return std::nullopt;
    return frames_[next_++];
  }

 private:
  std::vector<Frame> frames_;
  std::size_t next_ = 0;
};

TEST_CASE("The next frame is expected after the last one at the shots' cadence") {
  SyntheticCaptureOptions capture_options;
  capture_options.num_views = 5;
  std::vector<Frame> frames = testing::RenderedCapture(capture_options).frames;
  const auto t0 = std::chrono::steady_clock::now();
  const std::vector<double> arrivals_s = {0, 4, 7, 12, 15};  // intervals 4, 3, 5, 3
  for (std::size_t i = 0; i < frames.size(); ++i) {
    frames[i].arrival =
        t0 + std::chrono::duration_cast<std::chrono::steady_clock::duration>(
                 std::chrono::duration<double>(arrivals_s[i]));
  }
  StampedSource source(frames);
  PreparedFrameSource prepared(&source, Engine::Options());
  for (std::size_t i = 0; i < frames.size(); ++i) {
    // Too few shots for a cadence.
    if (i < 3) CHECK_FALSE(prepared.ShotCadence());
    REQUIRE(prepared.Next());
  }
  // Median interval 3.5 s (of 3, 3, 4, 5: the mean of the middle two).
  const std::optional<PreparedFrameSource::Cadence> cadence = prepared.ShotCadence();
  REQUIRE(cadence);
  CHECK(std::chrono::duration<double>(cadence->interval).count() == Approx(3.5).margin(1e-6));
  CHECK(std::chrono::duration<double>(cadence->next_arrival - t0).count() ==
        Approx(15 + 3.5).margin(1e-6));
}

// Hands out one frame when released.
class GatedSource : public ImageSource {
 public:
  explicit GatedSource(Frame frame) : frame_(std::move(frame)) {}
  std::optional<Frame> Next() override {
    std::unique_lock<std::mutex> lock(mutex_);
    changed_.wait(lock, [&] { return open_ || stopped_; });
    if (stopped_ || given_) return std::nullopt;
    given_ = true;
    return frame_;
  }
  void Open() {
    std::lock_guard<std::mutex> lock(mutex_);
    open_ = true;
    changed_.notify_all();
  }
  void Stop() override {
    std::lock_guard<std::mutex> lock(mutex_);
    stopped_ = true;
    changed_.notify_all();
  }

 private:
  Frame frame_;
  std::mutex mutex_;
  std::condition_variable changed_;
  bool open_ = false;
  bool stopped_ = false;
  bool given_ = false;
};

TEST_CASE("A frame has arrived once the source gave it, before it is prepared") {
  SyntheticCaptureOptions capture_options;
  capture_options.num_views = 2;
  GatedSource source(testing::RenderedCapture(capture_options).frames.front());
  PreparedFrameSource prepared(&source, Engine::Options());
  std::this_thread::sleep_for(std::chrono::milliseconds(50));
  CHECK_FALSE(prepared.Arrived());
  CHECK_FALSE(prepared.WaitReady());
  source.Open();
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(10);
  while (!prepared.Arrived() && std::chrono::steady_clock::now() < deadline) {
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  CHECK(prepared.Arrived());
  REQUIRE(prepared.Next());
  // The prefetch of the one after waits in the source again: the source is
  // done once it returns, so the end arrives too.
  while (!prepared.Arrived() && std::chrono::steady_clock::now() < deadline) {
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  CHECK(prepared.Arrived());
  CHECK_FALSE(prepared.Next());
}

TEST_CASE("Leaving the engine loop early does not wait for the next shot") {
  WaitingSource source;
  const auto start = std::chrono::steady_clock::now();
  {
    // What an exception leaving RunEngine's loop does: the prefetch is
    // waiting in the source's Next() when the prepared source goes.
    PreparedFrameSource prepared(&source, Engine::Options());
  }
  CHECK(std::chrono::steady_clock::now() - start < std::chrono::seconds(2));
}

TEST_CASE("Stop ends a paced list without waiting for the next interval") {
  SyntheticCaptureOptions capture_options;
  capture_options.num_views = 2;
  FrameListSource source(testing::RenderedCapture(capture_options).frames, 30.0);
  REQUIRE(source.Next());
  std::thread stopper([&] {
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
    source.Stop();
  });
  const auto start = std::chrono::steady_clock::now();
  CHECK_FALSE(source.Next());
  CHECK(std::chrono::steady_clock::now() - start < std::chrono::seconds(5));
  stopper.join();
}

}  // namespace
}  // namespace flysfm
