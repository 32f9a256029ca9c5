#pragma once

// An append-only file of tab-separated records that survives the process
// dying at any point: each record reaches the kernel in one write(2) before
// Append returns, so a crash (SIGSEGV, abort, SIGKILL) right after it keeps
// it. Fields are escaped (\t, \n, \\), so any file name fits in one field.
// Against power loss the records would also need fsync; like the other files
// of a run's folder, they do not get it (docs/live.md).

#include <filesystem>
#include <mutex>
#include <string>
#include <vector>

namespace flysfm {

class JournalFile {
 public:
  // Opens `path` for appending, creating it. Throws std::runtime_error
  // naming the path when it cannot.
  explicit JournalFile(const std::filesystem::path& path);
  ~JournalFile();
  JournalFile(const JournalFile&) = delete;
  JournalFile& operator=(const JournalFile&) = delete;

  // Thread-safe. Throws std::runtime_error when the write fails (disk full).
  void Append(const std::vector<std::string>& fields);
  // The line Append writes for `fields`, newline included.
  static std::string Line(const std::vector<std::string>& fields);

  // The records of `path` in order; none when it does not exist. A last line
  // without its newline (cut by a crash or a full disk) is left out.
  static std::vector<std::vector<std::string>> Read(const std::filesystem::path& path);

  const std::filesystem::path& path() const { return path_; }
  // For a write(2) where nothing else may run (a fatal-signal handler).
  int fd() const { return fd_; }

 private:
  std::filesystem::path path_;
  int fd_ = -1;
  std::mutex mutex_;
};

}  // namespace flysfm
