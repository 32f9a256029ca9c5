#include "io/formats/ply.h"

#include <fstream>
#include <sstream>

#include <catch2/catch.hpp>

#include "tests/testing/temp_dir.h"

namespace flysfm {
namespace {

TEST_CASE("PLY holds every point with its colour") {
  Reconstruction r;
  const camera_t camera_id = r.AddCamera(Camera::FromString("PINHOLE 1,1,0,0", 2, 2));
  const std::vector<Eigen::Vector2d> keypoints = {{0, 0}, {1, 1}};
  for (int i = 0; i < 2; ++i) {
    r.RegisterImage(r.AddImage("i" + std::to_string(i), camera_id, keypoints), Rigid3d());
  }
  r.AddPoint3D({1.5, -2, 3}, {{1, 0}, {2, 0}}, {10, 20, 30});
  r.AddPoint3D({4, 5, 6.25}, {{1, 1}, {2, 1}}, {40, 50, 60});
  const auto path = testing::MakeTempDir("ply_test") / "points.ply";
  WritePly(r, path);

  std::ifstream in(path, std::ios::binary);
  std::string line, header;
  while (std::getline(in, line) && line != "end_header") header += line + "\n";
  CHECK(header.find("format binary_little_endian 1.0") != std::string::npos);
  CHECK(header.find("element vertex 2") != std::string::npos);
  std::vector<std::pair<Eigen::Vector3d, std::array<std::uint8_t, 3>>> vertices(2);
  for (auto& [xyz, color] : vertices) {
    in.read(reinterpret_cast<char*>(xyz.data()), 3 * sizeof(double));
    in.read(reinterpret_cast<char*>(color.data()), 3);
  }
  REQUIRE(in);
  CHECK(in.peek() == EOF);
  for (const auto& [xyz, color] : vertices) {
    const bool first = xyz == Eigen::Vector3d(1.5, -2, 3);
    CHECK((first || xyz == Eigen::Vector3d(4, 5, 6.25)));
    CHECK(color == (first ? std::array<std::uint8_t, 3>{10, 20, 30}
                          : std::array<std::uint8_t, 3>{40, 50, 60}));
  }
}

}  // namespace
}  // namespace flysfm
