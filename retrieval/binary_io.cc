#include "retrieval/binary_io.h"

#include <cstring>

namespace flysfm {

void WriteHeader(std::ostream& out, const char (&magic)[9], std::uint32_t version) {
  out.write(magic, 8);
  WriteValue(out, version);
}

void ReadHeader(std::istream& in, const char (&magic)[9], std::uint32_t version) {
  char tag[8];
  if (!in.read(tag, 8) || std::memcmp(tag, magic, 8) != 0) {
    throw std::runtime_error(std::string("not a flysfm ") + magic + " section (bad magic)");
  }
  const auto found = ReadValue<std::uint32_t>(in, "version");
  if (found != version) {
    throw std::runtime_error(std::string(magic) + " version " + std::to_string(found) +
                             " is not supported (expected " + std::to_string(version) + ")");
  }
}

void WriteMatrix(std::ostream& out, const RowMatrixXf& matrix) {
  WriteValue(out, std::int64_t(matrix.rows()));
  WriteValue(out, std::int64_t(matrix.cols()));
  out.write(reinterpret_cast<const char*>(matrix.data()),
            std::streamsize(sizeof(float) * matrix.size()));
}

RowMatrixXf ReadMatrix(std::istream& in, const char* what, std::int64_t max_elements) {
  const auto rows = ReadValue<std::int64_t>(in, what);
  const auto cols = ReadValue<std::int64_t>(in, what);
  if (rows < 0 || cols < 0 || (cols > 0 && rows > max_elements / cols)) {
    throw std::runtime_error(std::string("corrupt model file: bad size of ") + what);
  }
  RowMatrixXf matrix(rows, cols);
  if (!in.read(reinterpret_cast<char*>(matrix.data()),
               std::streamsize(sizeof(float) * matrix.size()))) {
    throw std::runtime_error(std::string("model file truncated while reading ") + what);
  }
  return matrix;
}

}  // namespace flysfm
