#pragma once

// Shared by the tests of live sources (watched folder, CAMFI): small distinct
// JPEG shots, and pulling frames from a source with a deadline so that a
// broken source fails the test instead of hanging it.

#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <functional>
#include <mutex>
#include <thread>
#include <vector>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "io/sources/image_source.h"

namespace flysfm::testing {

// `count` JPEGs of random texture (different sizes, so their byte counts
// differ too), "shot00.jpg", "shot01.jpg", ...
inline std::vector<std::filesystem::path> WriteTestJpegs(const std::filesystem::path& dir,
                                                         int count, int seed = 1) {
  std::filesystem::create_directories(dir);
  std::vector<std::filesystem::path> files;
  cv::RNG random{std::uint64_t(seed)};
  for (int i = 0; i < count; ++i) {
    cv::Mat image(48 + 8 * i, 64, CV_8UC3);
    random.fill(image, cv::RNG::UNIFORM, 0, 256);
    char name[32];
    std::snprintf(name, sizeof(name), "shot%02d.jpg", i);
    files.push_back(dir / name);
    cv::imwrite(files.back().string(), image);
  }
  return files;
}

// Frames from `source` until `count` arrived or `timeout_seconds` passed;
// `stop` unblocks the source's Next() at the deadline.
inline std::vector<Frame> PullFrames(ImageSource* source, const std::function<void()>& stop,
                                     int count, double timeout_seconds) {
  std::mutex mutex;
  std::condition_variable done_changed;
  bool done = false;
  std::thread watchdog([&] {
    std::unique_lock<std::mutex> lock(mutex);
    if (!done_changed.wait_for(lock, std::chrono::duration<double>(timeout_seconds),
                               [&] { return done; })) {
      stop();
    }
  });
  std::vector<Frame> frames;
  while (int(frames.size()) < count) {
    std::optional<Frame> frame = source->Next();
    if (!frame) break;
    frames.push_back(std::move(*frame));
  }
  {
    std::lock_guard<std::mutex> lock(mutex);
    done = true;
  }
  done_changed.notify_all();
  watchdog.join();
  return frames;
}

}  // namespace flysfm::testing
