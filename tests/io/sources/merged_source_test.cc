#include "io/sources/merged_source.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <mutex>
#include <stdexcept>
#include <thread>

#include <catch2/catch.hpp>

namespace flysfm {
namespace {

using Clock = std::chrono::steady_clock;
using Order = MergedSourceOptions::Order;

// Frames named `prefix0`, `prefix1`, ... with the given timestamps.
std::vector<Frame> Frames(const std::string& prefix, const std::vector<double>& timestamps) {
  std::vector<Frame> frames;
  for (std::size_t i = 0; i < timestamps.size(); ++i) {
    Frame frame;
    frame.name = prefix + std::to_string(i);
    frame.timestamp = timestamps[i];
    frames.push_back(frame);
  }
  return frames;
}

std::vector<std::string> Names(const std::vector<Frame>& frames) {
  std::vector<std::string> names;
  for (const Frame& frame : frames) names.push_back(frame.name);
  return names;
}

// Every frame of `source` until it ends; a Next() that throws is counted.
std::vector<Frame> Drain(ImageSource* source, int* failures = nullptr) {
  std::vector<Frame> frames;
  while (true) {
    std::optional<Frame> frame;
    try {
      frame = source->Next();
    } catch (const std::runtime_error&) {
      if (failures != nullptr) ++*failures;
      continue;
    }
    if (!frame) return frames;
    frames.push_back(std::move(*frame));
  }
}

// A live source: Next() blocks until a frame is pushed or Stop() is called;
// after Stop() it hands on what it still holds, then nullopt.
class BlockingSource : public ImageSource {
 public:
  void Push(Frame frame) {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      frames_.push_back(std::move(frame));
    }
    changed_.notify_all();
  }
  std::optional<Frame> Next() override {
    std::unique_lock<std::mutex> lock(mutex_);
    changed_.wait(lock, [&] { return stopped_ || !frames_.empty(); });
    if (frames_.empty()) return std::nullopt;
    Frame frame = std::move(frames_.front());
    frames_.erase(frames_.begin());
    return frame;
  }
  void Stop() override {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      stopped_ = true;
    }
    changed_.notify_all();
  }

 private:
  std::mutex mutex_;
  std::condition_variable changed_;
  std::vector<Frame> frames_;
  bool stopped_ = false;
};

// Hands on `good` frames, then throws.
class ThrowingSource : public ImageSource {
 public:
  explicit ThrowingSource(int good) : good_(good) {}
  std::optional<Frame> Next() override {
    if (handed_ == good_) throw std::runtime_error("card reader unplugged");
    Frame frame;
    frame.name = "t" + std::to_string(handed_++);
    return frame;
  }

 private:
  int good_;
  int handed_ = 0;
};

// An endless source counting the frames asked of it.
class CountingSource : public ImageSource {
 public:
  std::optional<Frame> Next() override {
    if (stopped_) return std::nullopt;
    Frame frame;
    frame.name = "c" + std::to_string(asked_++);
    return frame;
  }
  void Stop() override { stopped_ = true; }
  int asked() const { return asked_; }

 private:
  std::atomic<int> asked_{0};
  std::atomic<bool> stopped_{false};
};

TEST_CASE("Source tags: a folder's base name or camfi-HOST, cleaned, made unique in order") {
  CHECK(SourceTagOfFolder("/data/shoot/alice") == "alice");
  CHECK(SourceTagOfFolder("/data/shoot/alice/") == "alice");
  CHECK(SourceTagOfFolder("bob") == "bob");
  CHECK(SourceTagOfFolder("/data/north side (2)") == "north_side__2_");
  CHECK(SourceTagOfFolder("..") == "source");
  CHECK(SourceTagOfCamfi("192.168.9.67") == "camfi-192.168.9.67");
  CHECK(UniqueSourceTags({"a", "b", "a", "a"}) ==
        std::vector<std::string>{"a", "b", "a-2", "a-3"});
  // A tag that happens to look like a made-up one is not given twice.
  CHECK(UniqueSourceTags({"a", "a-2", "a"}) == std::vector<std::string>{"a", "a-2", "a-3"});
  CHECK(UniqueSourceTags({"a", "a", "a-2"}) == std::vector<std::string>{"a", "a-2", "a-2-2"});
}

TEST_CASE("Merged frames are named <tag>/<name>, carry their tag and the merged clock") {
  FrameListSource a(Frames("IMG_", {0, 1}));
  FrameListSource b(Frames("IMG_", {0, 1}));
  MergedSource merged({{"alice", &a}, {"bob", &b}}, {Order::kRoundRobin});
  const std::vector<Frame> frames = Drain(&merged);
  CHECK(Names(frames) ==
        std::vector<std::string>{"alice/IMG_0", "bob/IMG_0", "alice/IMG_1", "bob/IMG_1"});
  for (std::size_t i = 0; i < frames.size(); ++i) {
    CHECK(frames[i].source == (i % 2 == 0 ? "alice" : "bob"));
    CHECK(frames[i].timestamp == double(i));
  }
  CHECK(merged.num_frames() == std::vector<int>{2, 2});
}

TEST_CASE("A single merged input passes its frames as they are") {
  FrameListSource a(Frames("IMG_", {7.5, 9.25}));
  MergedSource merged({{"alice", &a}});
  const std::vector<Frame> frames = Drain(&merged);
  REQUIRE(frames.size() == 2);
  CHECK(Names(frames) == std::vector<std::string>{"IMG_0", "IMG_1"});
  CHECK(frames[0].source.empty());
  CHECK(frames[1].timestamp == 9.25);
}

TEST_CASE("By capture time the inputs are interleaved as the shots were taken") {
  FrameListSource a(Frames("a", {1.0, 4.0, 5.0, 9.0}));
  FrameListSource b(Frames("b", {2.0, 3.0, 6.0}));
  FrameListSource c(Frames("c", {4.0, 8.0}));
  // queue_frames 1: the merge may not see more than each input's head.
  MergedSourceOptions options{Order::kCaptureTime, 1};
  MergedSource merged({{"A", &a}, {"B", &b}, {"C", &c}}, options);
  // 4.0 twice: the input given first goes first.
  CHECK(Names(Drain(&merged)) == std::vector<std::string>{"A/a0", "B/b0", "B/b1", "A/a1",
                                                          "C/c0", "A/a2", "B/b2", "C/c1",
                                                          "A/a3"});
}

TEST_CASE("Round robin takes one frame of each input in turn, passing over ended ones") {
  FrameListSource a(Frames("a", {0, 0, 0}));
  FrameListSource b(Frames("b", {0}));
  FrameListSource c(Frames("c", {0, 0}));
  MergedSource merged({{"A", &a}, {"B", &b}, {"C", &c}}, {Order::kRoundRobin});
  CHECK(Names(Drain(&merged)) ==
        std::vector<std::string>{"A/a0", "B/b0", "C/c0", "A/a1", "C/c1", "A/a2"});
}

TEST_CASE("Paced inputs each keep their own pace: n photographers give n frames per interval") {
  const double interval = 0.5;
  FrameListSource a(Frames("a", {0, 2, 4}), interval);
  FrameListSource b(Frames("b", {1, 3, 5}), interval);
  const Clock::time_point start = Clock::now();
  MergedSource merged({{"A", &a}, {"B", &b}}, {Order::kCaptureTime});
  const std::vector<Frame> frames = Drain(&merged);
  const double elapsed = std::chrono::duration<double>(Clock::now() - start).count();
  REQUIRE(Names(frames) == std::vector<std::string>{"A/a0", "B/b0", "A/a1", "B/b1", "A/a2",
                                                    "B/b2"});
  // Each input's k-th frame arrives k intervals after its first.
  for (std::size_t i = 0; i < frames.size(); ++i) {
    const double arrived = std::chrono::duration<double>(frames[i].arrival - start).count();
    CHECK(arrived >= (i / 2) * interval - 0.01);
  }
  // Three intervals' worth of shots each, side by side: two intervals from
  // the first to the last, not the five of one camera shooting all six.
  CHECK(elapsed < 4 * interval);
}

TEST_CASE("Stop() wakes a Next() blocked on silent live inputs, and loses no frame handed on") {
  BlockingSource live, store;
  // The store holds a shot it hands on only once stopped (CamfiSource's
  // stored shots, a watched folder's replay): it must come through.
  Frame stored;
  stored.name = "stored";
  MergedSource merged({{"A", &live}, {"B", &store}});
  Frame early;
  early.name = "early";
  live.Push(early);
  std::atomic<bool> returned{false};
  std::vector<Frame> frames;
  std::thread reader([&] {
    frames = Drain(&merged);
    returned = true;
  });
  std::this_thread::sleep_for(std::chrono::milliseconds(150));
  // Both inputs silent: the run loop waits.
  CHECK_FALSE(returned);
  store.Push(stored);
  const Clock::time_point before = Clock::now();
  merged.Stop();
  reader.join();
  CHECK(std::chrono::duration<double>(Clock::now() - before).count() < 5);
  std::vector<std::string> names = Names(frames);
  std::sort(names.begin(), names.end());
  CHECK(names == std::vector<std::string>{"A/early", "B/stored"});
}

TEST_CASE("An input that ends early lets the others go on, in every order") {
  for (const Order order : {Order::kArrival, Order::kCaptureTime, Order::kRoundRobin}) {
    FrameListSource a(Frames("a", {0}));
    FrameListSource b(Frames("b", {1, 2, 3}), 0.05);
    MergedSource merged({{"A", &a}, {"B", &b}}, {order});
    std::vector<std::string> names = Names(Drain(&merged));
    std::sort(names.begin(), names.end());
    CHECK(names == std::vector<std::string>{"A/a0", "B/b0", "B/b1", "B/b2"});
  }
}

TEST_CASE("An input that throws is reported at the end while the others go on") {
  ThrowingSource broken(1);
  FrameListSource good(Frames("g", {0, 1, 2}), 0.05);
  MergedSource merged({{"card", &broken}, {"cam", &good}}, {Order::kArrival});
  std::vector<std::string> names;
  while (true) {
    std::optional<Frame> frame;
    try {
      frame = merged.Next();
    } catch (const std::runtime_error& e) {
      // Once, after every frame of both.
      CHECK_THAT(e.what(), Catch::Contains("card: card reader unplugged"));
      CHECK(names.size() == 4);
      CHECK_FALSE(merged.Next());
      break;
    }
    REQUIRE(frame);
    names.push_back(frame->name);
  }
  std::sort(names.begin(), names.end());
  CHECK(names == std::vector<std::string>{"cam/g0", "cam/g1", "cam/g2", "card/t0"});
}

TEST_CASE("A reader runs at most queue_frames ahead of the run loop") {
  CountingSource endless;
  BlockingSource quiet;
  MergedSourceOptions options{Order::kArrival, 3};
  {
    MergedSource merged({{"fast", &endless}, {"quiet", &quiet}}, options);
    REQUIRE(merged.Next());
    std::this_thread::sleep_for(std::chrono::milliseconds(200));
    // One taken, three queued, one held by the reader waiting for room.
    CHECK(endless.asked() <= 1 + 3 + 1);
    CHECK(endless.asked() >= 1 + 3);
    // Destroyed with full queues and nobody taking: no hang.
  }
}

TEST_CASE("Bad merged sources are refused") {
  FrameListSource a(Frames("a", {0}));
  FrameListSource b(Frames("b", {0}));
  CHECK_THROWS_AS(MergedSource({}), std::invalid_argument);
  CHECK_THROWS_AS(MergedSource({{"x", &a}, {"x", &b}}), std::invalid_argument);
  CHECK_THROWS_AS(MergedSource({{"", &a}}), std::invalid_argument);
  CHECK_THROWS_AS(MergedSource({{"x", &a}}, {Order::kArrival, 0}), std::invalid_argument);
}

}  // namespace
}  // namespace flysfm
