#pragma once

// Little helpers for the versioned binary model files. Values are written in
// the machine's byte order (little-endian on every supported platform). A
// short or inconsistent file throws std::runtime_error naming what was being
// read: model files come from outside and must never crash the program.

#include <cstdint>
#include <istream>
#include <ostream>
#include <stdexcept>
#include <string>
#include <type_traits>

#include "retrieval/types.h"

namespace flysfm {

template <typename T>
void WriteValue(std::ostream& out, const T& value) {
  static_assert(std::is_trivially_copyable_v<T>);
  out.write(reinterpret_cast<const char*>(&value), sizeof(T));
}

template <typename T>
T ReadValue(std::istream& in, const char* what) {
  static_assert(std::is_trivially_copyable_v<T>);
  T value{};
  if (!in.read(reinterpret_cast<char*>(&value), sizeof(T))) {
    throw std::runtime_error(std::string("model file truncated while reading ") + what);
  }
  return value;
}

// An 8-character tag and a version; Read checks both.
void WriteHeader(std::ostream& out, const char (&magic)[9], std::uint32_t version);
void ReadHeader(std::istream& in, const char (&magic)[9], std::uint32_t version);

void WriteMatrix(std::ostream& out, const RowMatrixXf& matrix);
// Rejects sizes over `max_elements` before allocating, so a corrupt size
// field cannot exhaust memory.
RowMatrixXf ReadMatrix(std::istream& in, const char* what,
                       std::int64_t max_elements = std::int64_t(1) << 28);

}  // namespace flysfm
