#include "geometry/binary_io.h"

#include <array>
#include <cmath>
#include <cstring>

namespace flysfm {

void WriteCount(std::ostream& out, std::size_t count) { WriteValue(out, std::uint64_t(count)); }

std::size_t ReadCount(std::istream& in, const char* what, std::size_t max_count) {
  const auto count = ReadValue<std::uint64_t>(in, what);
  if (count > max_count) {
    throw std::runtime_error(std::string("corrupt file: ") + std::to_string(count) + " " +
                             what + " (at most " + std::to_string(max_count) + ")");
  }
  return std::size_t(count);
}

void WriteString(std::ostream& out, const std::string& text) {
  WriteCount(out, text.size());
  out.write(text.data(), std::streamsize(text.size()));
}

std::string ReadString(std::istream& in, const char* what) {
  // Names and paths: a 64 KiB bound is generous and stops a corrupt length.
  std::string text(ReadCount(in, what, std::size_t(1) << 16), '\0');
  if (!in.read(text.data(), std::streamsize(text.size()))) {
    throw std::runtime_error(std::string("file truncated while reading ") + what);
  }
  return text;
}

void WriteRigid3d(std::ostream& out, const Rigid3d& pose) {
  const double values[7] = {pose.rotation.w(),    pose.rotation.x(),    pose.rotation.y(),
                            pose.rotation.z(),    pose.translation.x(), pose.translation.y(),
                            pose.translation.z()};
  WriteValue(out, values);
}

Rigid3d ReadRigid3d(std::istream& in, const char* what) {
  const auto values = ReadValue<std::array<double, 7>>(in, what);
  Rigid3d pose;
  pose.rotation = Eigen::Quaterniond(values[0], values[1], values[2], values[3]);
  pose.translation = Eigen::Vector3d(values[4], values[5], values[6]);
  // Poses are kept normalised; BA moves them on the unit sphere.
  if (!(std::abs(pose.rotation.norm() - 1) < 1e-6) || !pose.translation.allFinite()) {
    throw std::runtime_error(std::string("corrupt file: ") + what + " is not a rigid motion");
  }
  return pose;
}

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

}  // namespace flysfm
