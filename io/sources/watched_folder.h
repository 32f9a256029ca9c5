#pragma once

// Live images dropped into a folder by something else: an FTP server the
// camera uploads to, a phone app, a card reader. A file is handed on once
// complete: its size and time unchanged for `stable_seconds` and its bytes a
// whole image (JPEG/PNG end marker). Each file once, in the order files
// appeared; a file is known by its device, inode, size and modification
// time, so one renamed or moved within the folder is not a new image. A file
// that stays incomplete is reported once, not processed (it is taken if it
// later completes). With a state file, what was handed on is recorded in
// order, and a restart hands the same files on again first, in that order.

#include <sys/types.h>

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <filesystem>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <set>
#include <string>
#include <tuple>
#include <vector>

#include "io/sources/image_source.h"
#include "io/sources/journal_file.h"

namespace flysfm {

struct WatchedFolderOptions {
  // How often the folder is listed (seconds).
  double poll_seconds = 0.2;
  // A file must keep its size and time this long before it is read.
  double stable_seconds = 1.0;
  // A file unchanged this long but still not a whole image is reported.
  double give_up_seconds = 30;
  // Sub-folders too, at any depth: a card's next folder (100CANON, then
  // 101CANON), an FTP upload's dated folders. Symbolic links to folders are
  // not followed (no loops) and hidden entries (".name", such as macOS's
  // "._IMG_0001.JPG") are left out.
  bool recursive = true;
  // Where each file handed on is recorded, in order (OUT/watched.tsv);
  // empty: nowhere, and a restart lists the folder anew.
  std::filesystem::path state_file;

  // False when an option is out of range; `error` then names it.
  bool Check(std::string* error = nullptr) const;
};

class WatchedFolderSource : public ImageSource {
 public:
  // Throws std::invalid_argument for bad options or a missing folder,
  // std::runtime_error when the state file cannot be written.
  WatchedFolderSource(const std::filesystem::path& dir, const WatchedFolderOptions& options);

  // The next complete file (bytes read and checked, so the engine decodes
  // exactly what was checked), named by its path below the folder; blocks;
  // nullopt once stopped. The files of the state file come first, even
  // after Stop().
  std::optional<Frame> Next() override;
  // Thread-safe.
  void Stop() override;

  // Files reported as never completing, or too large to read.
  int num_incomplete() const { return num_incomplete_; }
  // Files of the state file that are gone (neither at their path nor
  // renamed within the folder).
  int num_missing() const { return num_missing_; }
  // Distinct listing errors reported (an unmounted card, an unreadable
  // sub-folder, a symbolic link loop): each once until it changes.
  int num_listing_errors() const { return num_listing_errors_; }

 private:
  // A file's identity: a rename keeps it, a rewrite does not.
  using FileId = std::tuple<dev_t, ino_t, std::uintmax_t, std::int64_t>;
  struct Candidate {
    FileId id;
    std::chrono::steady_clock::time_point last_change;
    std::uint64_t order = 0;  // when first seen
    bool checked_incomplete = false;
    bool reported = false;
  };
  // Image files below the folder with their identities; listing errors
  // are reported when they change.
  std::map<std::string, FileId> List();
  void Scan();
  std::optional<Frame> TakeReplay();
  std::optional<Frame> TakeComplete();
  // The frame of `file`, recorded as handed on (`record`: in the state file).
  Frame HandOn(const std::string& file, const FileId& id, std::vector<std::uint8_t> bytes,
               bool record);

  std::filesystem::path dir_;
  WatchedFolderOptions options_;
  std::unique_ptr<JournalFile> state_;
  // The state file's files, still to be handed on again.
  std::deque<std::pair<std::string, FileId>> replay_;
  std::map<std::string, Candidate> candidates_;
  std::set<std::string> handed_on_;
  std::set<FileId> handed_on_ids_;
  std::set<std::string> listing_errors_;
  std::uint64_t next_order_ = 0;
  std::uint64_t num_handed_on_ = 0;  // this run's frames, replayed ones included
  std::atomic<int> num_incomplete_{0};
  std::atomic<int> num_missing_{0};
  std::atomic<int> num_listing_errors_{0};
  std::atomic<bool> stopping_{false};
  std::mutex mutex_;
  std::condition_variable wake_;
};

}  // namespace flysfm
