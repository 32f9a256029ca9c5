#include "io/sources/watched_folder.h"

#include <algorithm>
#include <iostream>
#include <stdexcept>

#include "io/sources/image_markers.h"
#include "matching/image_decode.h"

namespace flysfm {
namespace {

using Clock = std::chrono::steady_clock;

double SecondsSince(Clock::time_point t) {
  return std::chrono::duration<double>(Clock::now() - t).count();
}

}  // namespace

bool WatchedFolderOptions::Check() const {
  return poll_seconds > 0 && stable_seconds >= 0 && give_up_seconds > stable_seconds;
}

WatchedFolderSource::WatchedFolderSource(const std::filesystem::path& dir,
                                         const WatchedFolderOptions& options)
    : dir_(dir), options_(options) {
  if (!options_.Check()) throw std::invalid_argument("invalid watched-folder options");
  if (!std::filesystem::is_directory(dir_)) {
    throw std::invalid_argument("no folder " + dir_.string() + " to watch");
  }
}

void WatchedFolderSource::Stop() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stopping_ = true;
  }
  wake_.notify_all();
}

void WatchedFolderSource::Scan() {
  std::vector<std::string> files;
  try {
    files = ListImageFiles(dir_.string());
  } catch (const std::exception&) {
    // The folder vanished (an unmounted card): keep waiting for it.
    return;
  }
  for (const std::string& file : files) {
    if (handed_on_.count(file)) continue;
    std::error_code error;
    const std::uintmax_t size = std::filesystem::file_size(file, error);
    const std::filesystem::file_time_type time = std::filesystem::last_write_time(file, error);
    if (error) continue;
    const auto found = candidates_.find(file);
    if (found == candidates_.end()) {
      Candidate candidate;
      candidate.size = size;
      candidate.time = time;
      candidate.last_change = Clock::now();
      candidate.order = next_order_++;
      candidates_.emplace(file, candidate);
    } else if (found->second.size != size || found->second.time != time) {
      found->second.size = size;
      found->second.time = time;
      found->second.last_change = Clock::now();
      found->second.checked_incomplete = false;
    }
  }
}

std::optional<Frame> WatchedFolderSource::TakeComplete() {
  // Oldest first: files are handed on in the order they appeared.
  std::vector<std::pair<std::uint64_t, std::string>> ready;
  for (const auto& [file, candidate] : candidates_) {
    if (SecondsSince(candidate.last_change) >= options_.stable_seconds &&
        !candidate.checked_incomplete) {
      ready.emplace_back(candidate.order, file);
    }
  }
  std::sort(ready.begin(), ready.end());
  for (const auto& [order, file] : ready) {
    Candidate& candidate = candidates_[file];
    std::vector<std::uint8_t> bytes = ReadFileBytes(file);
    if (bytes.size() != candidate.size || !LooksCompleteImage(file, bytes)) {
      // Read again only once it changes.
      candidate.checked_incomplete = bytes.size() == candidate.size;
      continue;
    }
    Frame frame;
    frame.path = file;
    frame.name = frame.path.filename().string();
    frame.bytes = std::move(bytes);
    frame.timestamp = double(handed_on_.size());
    frame.arrival = candidate.last_change;
    handed_on_.insert(file);
    candidates_.erase(file);
    return frame;
  }
  for (auto& [file, candidate] : candidates_) {
    if (candidate.checked_incomplete && !candidate.reported &&
        SecondsSince(candidate.last_change) >= options_.give_up_seconds) {
      candidate.reported = true;
      ++num_incomplete_;
      std::cerr << "watch: " << file << " has not changed for " << options_.give_up_seconds
                << " s and is still not a whole image; not processed\n";
    }
  }
  return std::nullopt;
}

std::optional<Frame> WatchedFolderSource::Next() {
  std::unique_lock<std::mutex> lock(mutex_);
  while (!stopping_) {
    Scan();
    if (std::optional<Frame> frame = TakeComplete()) return frame;
    wake_.wait_for(lock, std::chrono::duration<double>(options_.poll_seconds),
                   [this] { return stopping_.load(); });
  }
  return std::nullopt;
}

}  // namespace flysfm
