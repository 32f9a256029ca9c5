#pragma once

// One flysfm process per output folder: two runs writing the same log,
// model and journals would interleave them. An exclusive flock(2) on
// OUT/.lock, held for the process's life; the kernel releases it when the
// process ends, crashed or not, so a stale lock never blocks a restart.

#include <filesystem>

namespace flysfm {

class OutputLock {
 public:
  // Creates `out_dir` and locks OUT/.lock, writing this process's id into
  // it. Throws std::runtime_error when another process (named by the id it
  // wrote) holds the lock, or the file cannot be opened.
  explicit OutputLock(const std::filesystem::path& out_dir);
  ~OutputLock();
  OutputLock(const OutputLock&) = delete;
  OutputLock& operator=(const OutputLock&) = delete;

 private:
  int fd_ = -1;
};

}  // namespace flysfm
