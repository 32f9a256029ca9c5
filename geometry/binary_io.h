#pragma once

// Little helpers for the project's versioned binary files (retrieval models,
// the engine's checkpoint). Values are written in the machine's byte order
// (little-endian on every supported platform). A short or inconsistent file
// throws std::runtime_error naming what was being read: such files come from
// disk, where a crash or a full disk may have cut them, and must never crash
// the program.

#include <cstdint>
#include <istream>
#include <ostream>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <vector>

#include "geometry/rigid3d.h"

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
    throw std::runtime_error(std::string("file truncated while reading ") + what);
  }
  return value;
}

// A count written before a sequence; on reading, one over `max_count` is a
// corrupt file, rejected before anything is allocated.
void WriteCount(std::ostream& out, std::size_t count);
std::size_t ReadCount(std::istream& in, const char* what, std::size_t max_count);

// A sequence of trivially copyable values, count first.
template <typename T>
void WriteVector(std::ostream& out, const std::vector<T>& values) {
  static_assert(std::is_trivially_copyable_v<T>);
  WriteCount(out, values.size());
  out.write(reinterpret_cast<const char*>(values.data()),
            std::streamsize(sizeof(T) * values.size()));
}

template <typename T>
std::vector<T> ReadVector(std::istream& in, const char* what,
                          std::size_t max_count = std::size_t(1) << 28) {
  static_assert(std::is_trivially_copyable_v<T>);
  std::vector<T> values(ReadCount(in, what, max_count));
  if (!in.read(reinterpret_cast<char*>(values.data()),
               std::streamsize(sizeof(T) * values.size()))) {
    throw std::runtime_error(std::string("file truncated while reading ") + what);
  }
  return values;
}

void WriteString(std::ostream& out, const std::string& text);
std::string ReadString(std::istream& in, const char* what);

void WriteRigid3d(std::ostream& out, const Rigid3d& pose);
// Throws on a rotation that is not a unit quaternion (a corrupt file).
Rigid3d ReadRigid3d(std::istream& in, const char* what);

// An 8-character tag and a version; Read checks both.
void WriteHeader(std::ostream& out, const char (&magic)[9], std::uint32_t version);
void ReadHeader(std::istream& in, const char (&magic)[9], std::uint32_t version);

}  // namespace flysfm
