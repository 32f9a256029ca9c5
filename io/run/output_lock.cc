#include "io/run/output_lock.h"

#include <fcntl.h>
#include <sys/file.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <stdexcept>
#include <string>

namespace flysfm {

OutputLock::OutputLock(const std::filesystem::path& out_dir) {
  std::filesystem::create_directories(out_dir);
  const std::filesystem::path path = out_dir / ".lock";
  fd_ = ::open(path.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
  if (fd_ < 0) {
    throw std::runtime_error("cannot open " + path.string() + ": " + std::strerror(errno));
  }
  if (::flock(fd_, LOCK_EX | LOCK_NB) != 0) {
    const int error = errno;
    char holder[32] = {};
    const ssize_t n = ::pread(fd_, holder, sizeof(holder) - 1, 0);
    ::close(fd_);
    fd_ = -1;
    const std::string pid = n > 0 ? std::string(holder, std::size_t(n)) : std::string();
    if (error == EWOULDBLOCK) {
      throw std::runtime_error(
          out_dir.string() + " is in use by another flysfm process" +
          (pid.empty() ? std::string() : " (pid " + pid.substr(0, pid.find('\n')) + ")") +
          "; give another --out or stop that process");
    }
    throw std::runtime_error("cannot lock " + path.string() + ": " + std::strerror(error));
  }
  // The id only lets a second process name this one: without it (a failed
  // write) the lock holds all the same.
  const std::string pid = std::to_string(::getpid()) + "\n";
  if (::ftruncate(fd_, 0) == 0) (void)!::pwrite(fd_, pid.data(), pid.size(), 0);
}

OutputLock::~OutputLock() {
  if (fd_ >= 0) ::close(fd_);
}

}  // namespace flysfm
