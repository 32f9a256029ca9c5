#pragma once

// Live images dropped into a folder by something else: an FTP server the
// camera uploads to, a phone app, a card reader. A file is handed on once
// complete: its size and time unchanged for `stable_seconds` and its bytes a
// whole image (JPEG/PNG end marker). Each file once, in the order files
// appeared. A file that stays incomplete is reported once, not processed
// (it is taken if it later completes).

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <filesystem>
#include <map>
#include <mutex>
#include <optional>
#include <set>
#include <string>

#include "io/sources/image_source.h"

namespace flysfm {

struct WatchedFolderOptions {
  // How often the folder is listed (seconds).
  double poll_seconds = 0.2;
  // A file must keep its size and time this long before it is read.
  double stable_seconds = 1.0;
  // A file unchanged this long but still not a whole image is reported.
  double give_up_seconds = 30;

  bool Check() const;
};

class WatchedFolderSource : public ImageSource {
 public:
  // Throws std::invalid_argument for bad options or a missing folder.
  WatchedFolderSource(const std::filesystem::path& dir, const WatchedFolderOptions& options);

  // The next complete file (bytes read and checked, so the engine decodes
  // exactly what was checked); blocks; nullopt once stopped.
  std::optional<Frame> Next() override;
  // Thread-safe.
  void Stop();

  // Files reported as never completing.
  int num_incomplete() const { return num_incomplete_; }

 private:
  struct Candidate {
    std::uintmax_t size = 0;
    std::filesystem::file_time_type time;
    std::chrono::steady_clock::time_point last_change;
    std::uint64_t order = 0;  // when first seen
    bool checked_incomplete = false;
    bool reported = false;
  };
  void Scan();
  std::optional<Frame> TakeComplete();

  std::filesystem::path dir_;
  WatchedFolderOptions options_;
  std::map<std::string, Candidate> candidates_;
  std::set<std::string> handed_on_;
  std::uint64_t next_order_ = 0;
  std::atomic<int> num_incomplete_{0};
  std::atomic<bool> stopping_{false};
  std::mutex mutex_;
  std::condition_variable wake_;
};

}  // namespace flysfm
