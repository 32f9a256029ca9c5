#include "tests/testing/frame_files.h"

#include <fstream>
#include <stdexcept>

namespace flysfm::testing {

std::vector<Frame> WriteFrameFiles(const std::vector<Frame>& frames,
                                   const std::filesystem::path& dir) {
  std::filesystem::create_directories(dir);
  std::vector<Frame> files;
  for (const Frame& frame : frames) {
    Frame file;
    file.name = frame.name;
    file.path = dir / frame.name;
    file.timestamp = frame.timestamp;
    std::ofstream out(file.path, std::ios::binary);
    out.write(reinterpret_cast<const char*>(frame.bytes.data()),
              std::streamsize(frame.bytes.size()));
    if (!out) throw std::runtime_error("cannot write " + file.path.string());
    files.push_back(file);
  }
  return files;
}

}  // namespace flysfm::testing
