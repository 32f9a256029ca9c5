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

TEST_CASE("PLY carries each point's quality measures when given them") {
  Reconstruction r;
  const camera_t camera_id = r.AddCamera(Camera::FromString("PINHOLE 1,1,0,0", 2, 2));
  const std::vector<Eigen::Vector2d> keypoints = {{0, 0}, {1, 1}};
  for (int i = 0; i < 2; ++i) {
    r.RegisterImage(r.AddImage("i" + std::to_string(i), camera_id, keypoints), Rigid3d());
  }
  const point3D_t measured = r.AddPoint3D({1, 2, 3}, {{1, 0}, {2, 0}}, {10, 20, 30});
  const point3D_t undefined = r.AddPoint3D({4, 5, 6}, {{1, 1}, {2, 1}}, {40, 50, 60});
  std::unordered_map<point3D_t, PointQuality> quality;
  quality[measured] = PointQuality{2, 12.5, 0.25, 0.0625, 0.015625};
  quality[undefined] = PointQuality{2, 0, 0.5, 0.5, std::nullopt};
  const auto path = testing::MakeTempDir("ply_quality_test") / "points.ply";
  WritePly(r, path, &quality);

  std::ifstream in(path, std::ios::binary);
  std::string line, header;
  while (std::getline(in, line) && line != "end_header") header += line + "\n";
  CHECK(header.find("property uchar blue\nproperty int views\nproperty float max_angle_deg\n"
                    "property float error_px\nproperty float sigma\n") != std::string::npos);
  int seen = 0;
  for (int v = 0; v < 2; ++v) {
    Eigen::Vector3d xyz;
    std::array<std::uint8_t, 3> color;
    std::int32_t views = 0;
    float values[3];
    in.read(reinterpret_cast<char*>(xyz.data()), 3 * sizeof(double));
    in.read(reinterpret_cast<char*>(color.data()), 3);
    in.read(reinterpret_cast<char*>(&views), sizeof(views));
    in.read(reinterpret_cast<char*>(values), sizeof(values));
    REQUIRE(in);
    CHECK(views == 2);
    if (xyz == Eigen::Vector3d(1, 2, 3)) {
      ++seen;
      CHECK(values[0] == 12.5f);
      CHECK(values[1] == 0.25f);
      CHECK(values[2] == 0.015625f);
    } else {
      seen += 2;
      CHECK(values[1] == 0.5f);
      CHECK(values[2] == kPlyUndefinedSigma);
    }
  }
  CHECK(seen == 3);
  CHECK(in.peek() == EOF);
}

}  // namespace
}  // namespace flysfm
