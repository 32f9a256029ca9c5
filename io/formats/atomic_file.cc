#include "io/formats/atomic_file.h"

#include <fstream>
#include <stdexcept>

namespace flysfm {

void WriteFileAtomically(const std::filesystem::path& path,
                         const std::function<void(std::ostream&)>& write,
                         bool binary) {
  std::filesystem::path temporary = path;
  temporary += ".tmp";
  {
    std::ofstream out(temporary, binary ? std::ios::binary : std::ios::out);
    if (!out) throw std::runtime_error("cannot write " + temporary.string());
    write(out);
    out.flush();
    if (!out) throw std::runtime_error("error while writing " + temporary.string());
  }
  std::error_code error;
  std::filesystem::rename(temporary, path, error);
  if (error) {
    throw std::runtime_error("cannot replace " + path.string() + ": " +
                             error.message());
  }
}

}  // namespace flysfm
