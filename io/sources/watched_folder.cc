#include "io/sources/watched_folder.h"

#include <sys/stat.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <iostream>
#include <stdexcept>
#include <vector>

#include "io/sources/image_markers.h"
#include "matching/image_decode.h"

namespace flysfm {
namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

double SecondsSince(Clock::time_point t) {
  return std::chrono::duration<double>(Clock::now() - t).count();
}

}  // namespace

bool WatchedFolderOptions::Check(std::string* error) const {
  const char* bad = !(poll_seconds > 0)                ? "poll_seconds must be > 0"
                    : !(stable_seconds >= 0)           ? "stable_seconds must be >= 0"
                    : !(give_up_seconds > stable_seconds)
                        ? "give_up_seconds must be greater than stable_seconds"
                        : nullptr;
  if (bad != nullptr && error != nullptr) *error = bad;
  return bad == nullptr;
}

WatchedFolderSource::WatchedFolderSource(const fs::path& dir,
                                         const WatchedFolderOptions& options)
    : dir_(dir), options_(options) {
  std::string error;
  if (!options_.Check(&error)) {
    throw std::invalid_argument("watched-folder options: " + error);
  }
  if (!fs::is_directory(dir_)) {
    throw std::invalid_argument("no folder " + dir_.string() + " to watch");
  }
  if (options_.state_file.empty()) return;
  for (const std::vector<std::string>& record : JournalFile::Read(options_.state_file)) {
    try {
      if (record.size() != 5) throw std::invalid_argument("expected 5 fields");
      const FileId id{dev_t(std::stoull(record[1])), ino_t(std::stoull(record[2])),
                      std::uintmax_t(std::stoull(record[3])), std::int64_t(std::stoll(record[4]))};
      replay_.emplace_back(record[0], id);
      handed_on_.insert((dir_ / record[0]).string());
      handed_on_ids_.insert(id);
    } catch (const std::exception&) {
      std::cerr << "watch: " << options_.state_file.string()
                << ": a damaged record is left out\n";
    }
  }
  state_ = std::make_unique<JournalFile>(options_.state_file);
}

void WatchedFolderSource::Stop() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stopping_ = true;
  }
  wake_.notify_all();
}

std::map<std::string, WatchedFolderSource::FileId> WatchedFolderSource::List() {
  std::map<std::string, FileId> files;
  std::set<std::string> errors;
  std::vector<fs::path> folders = {dir_};
  while (!folders.empty()) {
    const fs::path folder = folders.back();
    folders.pop_back();
    std::error_code error;
    fs::directory_iterator entries(folder, error);
    for (; !error && entries != fs::directory_iterator(); entries.increment(error)) {
      const fs::path& path = entries->path();
      if (path.filename().string()[0] == '.') continue;
      std::error_code type_error;
      if (options_.recursive && entries->is_directory(type_error) &&
          !entries->is_symlink(type_error)) {
        folders.push_back(path);
        continue;
      }
      if (!HasImageExtension(path.string())) continue;
      struct stat info;
      if (::stat(path.c_str(), &info) != 0) {
        // A file deleted since the listing is no error.
        if (errno != ENOENT) errors.insert(path.string() + ": " + std::strerror(errno));
        continue;
      }
      if (!S_ISREG(info.st_mode)) continue;
      files[path.string()] =
          FileId{info.st_dev, info.st_ino, std::uintmax_t(info.st_size),
                 std::int64_t(info.st_mtim.tv_sec) * 1000000000 + info.st_mtim.tv_nsec};
    }
    // A sub-folder removed since it was listed is no error; the folder
    // itself gone (an unmounted card) is, and it is waited for.
    if (error && (folder == dir_ || error != std::errc::no_such_file_or_directory)) {
      errors.insert("cannot list " + folder.string() + ": " + error.message());
    }
  }
  // Each error once, however many polls it lasts.
  for (const std::string& error : errors) {
    if (listing_errors_.count(error) == 0) {
      std::cerr << "watch: " << error << "\n";
      ++num_listing_errors_;
    }
  }
  if (errors.empty() && !listing_errors_.empty()) {
    std::cerr << "watch: " << dir_.string() << " is listed without errors again\n";
  }
  listing_errors_ = std::move(errors);
  return files;
}

void WatchedFolderSource::Scan() {
  const std::map<std::string, FileId> files = List();
  // A candidate gone from its path (renamed, moved, deleted) is not waited
  // for there; under a new name it is found again.
  for (auto it = candidates_.begin(); it != candidates_.end();) {
    it = files.count(it->first) ? std::next(it) : candidates_.erase(it);
  }
  for (const auto& [file, id] : files) {
    if (handed_on_.count(file) || handed_on_ids_.count(id)) continue;
    const auto found = candidates_.find(file);
    if (found == candidates_.end()) {
      Candidate candidate;
      candidate.id = id;
      candidate.last_change = Clock::now();
      candidate.order = next_order_++;
      candidates_.emplace(file, candidate);
    } else if (found->second.id != id) {
      found->second.id = id;
      found->second.last_change = Clock::now();
      found->second.checked_incomplete = false;
    }
  }
}

Frame WatchedFolderSource::HandOn(const std::string& file, const FileId& id,
                                  std::vector<std::uint8_t> bytes, bool record) {
  Frame frame;
  frame.path = file;
  frame.name = frame.path.lexically_relative(dir_).generic_string();
  if (record && state_) {
    // In the state file before the engine sees it, as the CAMFI journal.
    state_->Append({frame.name, std::to_string(std::get<0>(id)),
                    std::to_string(std::get<1>(id)), std::to_string(std::get<2>(id)),
                    std::to_string(std::get<3>(id))});
  }
  frame.bytes = std::move(bytes);
  frame.timestamp = double(num_handed_on_++);
  handed_on_.insert(file);
  handed_on_ids_.insert(id);
  return frame;
}

std::optional<Frame> WatchedFolderSource::TakeReplay() {
  std::optional<std::map<std::string, FileId>> listing;
  while (!replay_.empty()) {
    const auto [name, id] = replay_.front();
    replay_.pop_front();
    std::string file = (dir_ / name).string();
    std::vector<std::uint8_t> bytes = ReadFileBytes(file);
    if (bytes.empty()) {
      // Renamed or moved within the folder while the program was down.
      if (!listing) listing = List();
      for (const auto& [path, current] : *listing) {
        if (current == id) {
          file = path;
          bytes = ReadFileBytes(file);
          break;
        }
      }
    }
    if (bytes.empty() || !LooksCompleteImage(file, bytes)) {
      ++num_missing_;
      std::cerr << "watch: " << name << ", processed before the restart, is gone or "
                << "damaged; the model is rebuilt without it\n";
      continue;
    }
    Frame frame = HandOn(file, id, std::move(bytes), /*record=*/false);
    frame.arrival = Clock::now();
    return frame;
  }
  return std::nullopt;
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
  const std::uintmax_t max_bytes = DecodeOptions().max_file_bytes;
  for (const auto& [order, file] : ready) {
    Candidate& candidate = candidates_[file];
    const std::uintmax_t size = std::get<2>(candidate.id);
    if (size > max_bytes) {
      candidate.checked_incomplete = true;
      candidate.reported = true;
      ++num_incomplete_;
      std::cerr << "watch: " << file << " holds " << size << " bytes, above max_file_bytes ("
                << max_bytes << "); not processed\n";
      continue;
    }
    std::vector<std::uint8_t> bytes = ReadFileBytes(file);
    if (bytes.size() != size || !LooksCompleteImage(file, bytes)) {
      // Read again only once it changes.
      candidate.checked_incomplete = bytes.size() == size;
      continue;
    }
    const FileId id = candidate.id;
    const Clock::time_point arrival = candidate.last_change;
    candidates_.erase(file);
    Frame frame = HandOn(file, id, std::move(bytes), /*record=*/true);
    frame.arrival = arrival;
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
  if (std::optional<Frame> frame = TakeReplay()) return frame;
  while (!stopping_) {
    Scan();
    if (std::optional<Frame> frame = TakeComplete()) return frame;
    wake_.wait_for(lock, std::chrono::duration<double>(options_.poll_seconds),
                   [this] { return stopping_.load(); });
  }
  return std::nullopt;
}

}  // namespace flysfm
