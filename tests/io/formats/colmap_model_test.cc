#include "io/formats/colmap_model.h"

#include <fstream>

#include <catch2/catch.hpp>

#include "tests/testing/synthetic.h"
#include "tests/testing/temp_dir.h"

namespace flysfm {
namespace {

namespace fs = std::filesystem;

// A reconstruction of a noisy synthetic scene with two cameras, one image
// left unregistered, and coloured points.
Reconstruction MakeReconstruction() {
  testing::SyntheticSceneOptions options;
  options.num_images = 5;
  options.num_points = 150;
  options.noise_px = 0.3;
  options.camera = Camera::FromString(
      "FULL_OPENCV 517.3,516.5,318.6,255.3,0.2624,-0.9531,-0.0054,0.0026,1.1633,0,0,0",
      640, 480);
  const testing::SyntheticScene scene = testing::MakeSyntheticScene(options);
  Reconstruction r;
  const camera_t camera_id = r.AddCamera(scene.camera);
  r.AddCamera(Camera::FromString("SIMPLE_RADIAL 800,400,300,-0.01", 800, 600));
  std::vector<std::vector<TrackElement>> tracks(scene.points.size());
  for (int i = 0; i < options.num_images; ++i) {
    std::vector<Eigen::Vector2d> keypoints;
    for (const auto& obs : scene.ObservationsOf(i)) {
      if (i < 4) tracks[obs.point].push_back({image_t(i + 1), point2D_t(keypoints.size())});
      keypoints.push_back(obs.pixel);
    }
    keypoints.emplace_back(1.5, 2.5);  // a keypoint observing nothing
    r.AddImage("frame " + std::to_string(i) + ".png", camera_id, keypoints);
    if (i < 4) r.RegisterImage(image_t(i + 1), scene.cams_from_world[i]);
  }
  for (std::size_t p = 0; p < scene.points.size(); ++p) {
    if (tracks[p].size() >= 2) {
      r.AddPoint3D(scene.points[p], tracks[p],
                   {std::uint8_t(p), std::uint8_t(2 * p), std::uint8_t(255 - p)});
    }
  }
  r.UpdatePointErrors();
  return r;
}

void CheckSameModel(const Reconstruction& a, const Reconstruction& b) {
  REQUIRE(a.cameras().size() == b.cameras().size());
  for (const auto& [id, camera] : a.cameras()) {
    CHECK(b.camera(id).model_id == camera.model_id);
    REQUIRE(b.camera(id).params.size() == camera.params.size());
    for (std::size_t i = 0; i < camera.params.size(); ++i) {
      CHECK(b.camera(id).params[i] == Approx(camera.params[i]).margin(1e-12));
    }
    CHECK(b.camera(id).width == camera.width);
  }
  REQUIRE(a.NumRegisteredImages() == b.NumRegisteredImages());
  for (const auto& [id, image] : a.images()) {
    if (!image.IsRegistered()) continue;
    const Image& other = b.image(id);
    CHECK(other.name == image.name);
    CHECK(other.cam_from_world->rotation.coeffs() == image.cam_from_world->rotation.coeffs());
    CHECK(other.cam_from_world->translation == image.cam_from_world->translation);
    REQUIRE(other.points2D.size() == image.points2D.size());
    for (std::size_t i = 0; i < image.points2D.size(); ++i) {
      CHECK((other.points2D[i].xy - image.points2D[i].xy).norm() < 1e-12);
      CHECK(other.points2D[i].point3D_id == image.points2D[i].point3D_id);
    }
  }
  REQUIRE(a.NumPoints3D() == b.NumPoints3D());
  for (const auto& [id, point] : a.points3D()) {
    const Point3D& other = b.point3D(id);
    CHECK(other.xyz == point.xyz);
    CHECK(other.color == point.color);
    CHECK(other.error == point.error);
    CHECK(other.track == point.track);
  }
}

TEST_CASE("COLMAP text and binary models round-trip exactly") {
  const Reconstruction original = MakeReconstruction();
  REQUIRE(original.NumPoints3D() > 50);
  const fs::path dir = testing::MakeTempDir("colmap_roundtrip");
  WriteColmapModel(original, dir);
  for (const char* file : {"cameras.txt", "images.txt", "points3D.txt",
                           "cameras.bin", "images.bin", "points3D.bin"}) {
    CHECK(fs::exists(dir / file));
    CHECK_FALSE(fs::exists(dir / (std::string(file) + ".tmp")));
  }
  CheckSameModel(original, ReadColmapText(dir));
  CheckSameModel(original, ReadColmapBinary(dir));
  // Unregistered images are not written, as COLMAP does.
  CHECK(ReadColmapModel(dir).images().size() == 4);
}

TEST_CASE("Files follow COLMAP's pixel convention, centre of pixel (0,0) at 0.5") {
  Reconstruction r;
  const camera_t camera_id = r.AddCamera(Camera::FromString("PINHOLE 500,500,319.5,239.5", 640, 480));
  const std::vector<Eigen::Vector2d> keypoints = {{10, 20}, {30, 40}};
  for (int i = 0; i < 2; ++i) r.RegisterImage(r.AddImage("i" + std::to_string(i), camera_id, keypoints), Rigid3d());
  r.AddPoint3D({0, 0, 1}, {{1, 0}, {2, 0}});
  const fs::path dir = testing::MakeTempDir("colmap_convention");
  WriteColmapText(r, dir);
  std::ifstream cameras(dir / "cameras.txt");
  std::string line;
  while (std::getline(cameras, line) && line[0] == '#') {}
  CHECK(line == "1 PINHOLE 640 480 500 500 320 240");
  std::ifstream images(dir / "images.txt");
  while (std::getline(images, line) && line[0] == '#') {}
  std::getline(images, line);
  CHECK(line == "10.5 20.5 1 30.5 40.5 -1");
}

TEST_CASE("Corrupt COLMAP models give errors naming the file") {
  using Catch::Matchers::Contains;
  const Reconstruction original = MakeReconstruction();
  const fs::path dir = testing::MakeTempDir("colmap_corrupt");
  WriteColmapModel(original, dir);

  SECTION("truncated binary") {
    fs::resize_file(dir / "points3D.bin", fs::file_size(dir / "points3D.bin") / 2);
    CHECK_THROWS_WITH(ReadColmapBinary(dir), Contains("points3D.bin") && Contains("truncated"));
  }
  SECTION("implausible binary count") {
    std::fstream f(dir / "images.bin", std::ios::in | std::ios::out | std::ios::binary);
    const std::uint64_t huge = ~std::uint64_t(0) >> 4;
    f.write(reinterpret_cast<const char*>(&huge), sizeof(huge));
    f.close();
    CHECK_THROWS_WITH(ReadColmapBinary(dir), Contains("implausible count"));
  }
  SECTION("malformed text line") {
    std::ofstream(dir / "cameras.txt") << "1 PINHOLE 640 480 500 500 320\n";
    CHECK_THROWS_WITH(ReadColmapText(dir), Contains("cameras.txt:1") &&
                                               Contains("takes 4 parameters"));
  }
  SECTION("track naming a missing image") {
    std::ofstream(dir / "points3D.txt") << "7 0 0 1 1 2 3 0.5 99 0 1 0\n";
    CHECK_THROWS_WITH(ReadColmapText(dir), Contains("missing image"));
  }
  SECTION("missing folder") {
    CHECK_THROWS_WITH(ReadColmapModel(dir / "nowhere"), Contains("cannot open"));
  }
}

}  // namespace
}  // namespace flysfm
