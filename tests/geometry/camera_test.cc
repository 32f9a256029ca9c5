#include "geometry/camera.h"

#include <random>

#include <Eigen/Geometry>

#include <catch2/catch.hpp>

namespace flysfm {
namespace {

// One representative instance per model, with realistic distortion.
std::vector<Camera> AllModels() {
  return {
      Camera::FromString("SIMPLE_PINHOLE 500,320,240", 640, 480),
      Camera::FromString("PINHOLE 510,495,318,245", 640, 480),
      Camera::FromString("SIMPLE_RADIAL 500,320,240,-0.08", 640, 480),
      Camera::FromString("RADIAL 500,320,240,-0.1,0.02", 640, 480),
      // A typical wide-angle lens (barrel distortion, slight decentering).
      // fr1's k1, k2 without its k3 would fold over at the corners and have no
      // inverse there.
      Camera::FromString("OPENCV 517.3,516.5,318.6,255.3,-0.28,0.07,0.001,-0.0005",
                         640, 480),
      // TUM freiburg1, the published calibration (k3 = 1.1633).
      Camera::FromString("FULL_OPENCV 517.3,516.5,318.6,255.3,0.2624,-0.9531,"
                         "-0.0054,0.0026,1.1633,0,0,0",
                         640, 480),
  };
}

TEST_CASE("Unproject then project returns the pixel over the whole image") {
  for (const Camera& camera : AllModels()) {
    INFO(camera.ToString());
    double max_error = 0;
    for (double y = 0; y <= camera.height; y += 4) {
      for (double x = 0; x <= camera.width; x += 4) {
        const Eigen::Vector2d pixel(x, y);
        const Eigen::Vector2d ray = camera.CamFromImg(pixel);
        const Eigen::Vector2d back = camera.ImgFromCam(ray.homogeneous());
        max_error = std::max(max_error, (back - pixel).norm());
      }
    }
    CHECK(max_error < 1e-8);
  }
}

TEST_CASE("Project then unproject returns the ray") {
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> uniform(-0.5, 0.5);
  for (const Camera& camera : AllModels()) {
    INFO(camera.ToString());
    for (int i = 0; i < 1000; ++i) {
      const Eigen::Vector3d point(uniform(rng), uniform(rng), 1.0 + uniform(rng) + 0.6);
      const Eigen::Vector2d ray = camera.CamFromImg(camera.ImgFromCam(point));
      CHECK((ray - point.hnormalized()).norm() < 1e-10);
    }
  }
}

TEST_CASE("Pinhole projection follows the focal length and principal point") {
  const Camera camera = Camera::FromString("PINHOLE 500,400,320,240", 640, 480);
  const Eigen::Vector2d pixel = camera.ImgFromCam(Eigen::Vector3d(0.2, -0.1, 2.0));
  CHECK(pixel.x() == Approx(320 + 500 * 0.1));
  CHECK(pixel.y() == Approx(240 - 400 * 0.05));
  CHECK(camera.MeanFocalLength() == Approx(450));
  CHECK(camera.CamFromImgThreshold(4.5) == Approx(0.01));
}

TEST_CASE("Camera strings round-trip exactly") {
  for (const Camera& camera : AllModels()) {
    const Camera parsed =
        Camera::FromString(camera.ToString(), camera.width, camera.height);
    CHECK(parsed.model_id == camera.model_id);
    CHECK(parsed.params == camera.params);
  }
  const Camera spaced = Camera::FromString("PINHOLE 1 2 3 4", 10, 10);
  CHECK(spaced.params == std::vector<double>{1, 2, 3, 4});
}

TEST_CASE("Malformed camera strings give clear errors") {
  using Catch::Matchers::Contains;
  CHECK_THROWS_WITH(Camera::FromString("FISHEYE 1,2,3", 1, 1),
                    Contains("unknown camera model 'FISHEYE'") &&
                        Contains("FULL_OPENCV"));
  CHECK_THROWS_WITH(Camera::FromString("PINHOLE 1,2,3", 1, 1),
                    Contains("takes 4 parameters (fx, fy, cx, cy), got 3"));
  CHECK_THROWS_WITH(Camera::FromString("PINHOLE 1,2,x,4", 1, 1),
                    Contains("'x' is not a finite number"));
  CHECK_THROWS_WITH(Camera::FromString("PINHOLE 1,2,nan,4", 1, 1),
                    Contains("not a finite number"));
  CHECK_THROWS_WITH(Camera::FromString("PINHOLE -1,2,3,4", 1, 1),
                    Contains("non-positive focal"));
  CHECK_THROWS_WITH(Camera::FromString("", 1, 1), Contains("empty"));
}

TEST_CASE("Models carry COLMAP's ids, names and parameter counts") {
  CHECK(CameraModelIdFromName("SIMPLE_PINHOLE") == CameraModelId::kSimplePinhole);
  CHECK(static_cast<int>(CameraModelIdFromName("FULL_OPENCV")) == 6);
  CHECK(static_cast<int>(CameraModelIdFromName("OPENCV")) == 4);
  CHECK(CameraModelNumParams(CameraModelId::kSimpleRadial) == 4);
  CHECK(CameraModelNumParams(CameraModelId::kRadial) == 5);
  CHECK(CameraModelNumParams(CameraModelId::kFullOpenCV) == 12);
  const Camera camera = Camera::FromFocal(CameraModelId::kSimpleRadial, 800, 640, 480);
  CHECK(camera.ToString() == "SIMPLE_RADIAL 800,319.5,239.5,0");
}

TEST_CASE("FromFocal puts the principal point at the image centre, pixel centres at integers") {
  // A 4 x 2 image: pixel centres at x = 0..3, y = 0..1; the centre between.
  const Camera camera = Camera::FromFocal(CameraModelId::kSimpleRadial, 10, 4, 2);
  CHECK(camera.params[1] == 1.5);
  CHECK(camera.params[2] == 0.5);
  // The optical axis meets the image halfway between the middle pixels.
  CHECK(camera.ImgFromCam(Eigen::Vector3d(0, 0, 1)).isApprox(Eigen::Vector2d(1.5, 0.5)));
}

}  // namespace
}  // namespace flysfm
