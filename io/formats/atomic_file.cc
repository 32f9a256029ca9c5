#include "io/formats/atomic_file.h"

#include <cerrno>
#include <cstring>
#include <fstream>
#include <stdexcept>
#include <string>

namespace flysfm {
namespace {

// errno's message when a stream failed with one set (a full disk, a missing
// folder), else the stream's generic failure.
std::string Reason() {
  return errno != 0 ? std::strerror(errno) : "stream error";
}

}  // namespace

void WriteFileAtomically(const std::filesystem::path& path,
                         const std::function<void(std::ostream&)>& write,
                         bool binary) {
  std::filesystem::path temporary = path;
  temporary += ".tmp";
  // A temporary left behind would fill a full disk further and confuse the
  // next writer; whatever went wrong, it goes.
  const auto fail = [&](const std::string& message) {
    std::error_code ignored;
    std::filesystem::remove(temporary, ignored);
    throw std::runtime_error(message);
  };
  {
    errno = 0;
    std::ofstream out(temporary, binary ? std::ios::binary : std::ios::out);
    if (!out) fail("cannot write " + temporary.string() + ": " + Reason());
    try {
      write(out);
    } catch (const std::exception& e) {
      out.close();
      fail("error while writing " + temporary.string() + ": " + e.what());
    }
    errno = 0;
    out.flush();
    if (!out) fail("error while writing " + temporary.string() + ": " + Reason());
    out.close();
    if (!out) fail("error while closing " + temporary.string() + ": " + Reason());
  }
  std::error_code error;
  std::filesystem::rename(temporary, path, error);
  if (error) fail("cannot replace " + path.string() + ": " + error.message());
}

}  // namespace flysfm
