#include "retrieval/binary_io.h"

namespace flysfm {

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
    throw std::runtime_error(std::string("file truncated while reading ") + what);
  }
  return matrix;
}

}  // namespace flysfm
