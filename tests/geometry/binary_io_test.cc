#include "geometry/binary_io.h"

#include <sstream>

#include <catch2/catch.hpp>

namespace flysfm {

TEST_CASE("Values, sequences, strings and poses read back as written") {
  std::stringstream stream;
  WriteHeader(stream, "TESTFILE", 3);
  WriteValue(stream, 42.5);
  WriteVector(stream, std::vector<int>{1, -2, 3});
  WriteString(stream, "IMG_0001.JPG");
  const Rigid3d pose(Eigen::Quaterniond(0.5, 0.5, -0.5, 0.5), Eigen::Vector3d(1, 2, 3));
  WriteRigid3d(stream, pose);

  ReadHeader(stream, "TESTFILE", 3);
  CHECK(ReadValue<double>(stream, "value") == 42.5);
  CHECK(ReadVector<int>(stream, "ints") == std::vector<int>{1, -2, 3});
  CHECK(ReadString(stream, "name") == "IMG_0001.JPG");
  const Rigid3d read = ReadRigid3d(stream, "pose");
  CHECK(read.rotation.coeffs() == pose.rotation.coeffs());
  CHECK(read.translation == pose.translation);
  CHECK_THROWS_WITH(ReadValue<int>(stream, "one more"),
                    Catch::Contains("truncated while reading one more"));
}

TEST_CASE("A wrong tag or version, an oversized count or a non-rigid pose is refused") {
  std::stringstream header;
  WriteHeader(header, "TESTFILE", 3);
  CHECK_THROWS_WITH(ReadHeader(header, "OTHERTAG", 3), Catch::Contains("bad magic"));
  header.seekg(0);
  CHECK_THROWS_WITH(ReadHeader(header, "TESTFILE", 4), Catch::Contains("version 3"));

  std::stringstream count;
  WriteCount(count, 1000);
  CHECK_THROWS_WITH(ReadVector<double>(count, "values", 999), Catch::Contains("corrupt"));

  std::stringstream pose;
  WriteValue(pose, std::array<double, 7>{2, 0, 0, 0, 0, 0, 0});
  CHECK_THROWS_WITH(ReadRigid3d(pose, "pose"), Catch::Contains("not a rigid motion"));
}

}  // namespace flysfm
