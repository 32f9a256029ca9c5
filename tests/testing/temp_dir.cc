#include "tests/testing/temp_dir.h"

#include <cstdlib>
#include <mutex>
#include <stdexcept>
#include <vector>

namespace flysfm::testing {
namespace {

// The folders made so far; its destructor runs at exit.
class TempDirs {
 public:
  ~TempDirs() {
    for (const std::filesystem::path& dir : dirs_) {
      std::error_code ignored;
      std::filesystem::remove_all(dir, ignored);
    }
  }

  std::filesystem::path Make(const std::string& name) {
    std::string pattern =
        (std::filesystem::temp_directory_path() / ("flysfm_" + name + "_XXXXXX")).string();
    if (::mkdtemp(pattern.data()) == nullptr) {
      throw std::runtime_error("cannot create a temporary folder " + pattern);
    }
    std::lock_guard<std::mutex> lock(mutex_);
    dirs_.push_back(pattern);
    return dirs_.back();
  }

 private:
  std::mutex mutex_;
  std::vector<std::filesystem::path> dirs_;
};

}  // namespace

std::filesystem::path MakeTempDir(const std::string& name) {
  static TempDirs dirs;
  return dirs.Make(name);
}

}  // namespace flysfm::testing
