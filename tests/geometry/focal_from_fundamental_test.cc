#include "geometry/focal_from_fundamental.h"

#include <cmath>
#include <limits>
#include <random>

#include <catch2/catch.hpp>

#include "geometry/camera.h"
#include "geometry/essential_matrix.h"
#include "geometry/fundamental_matrix.h"
#include "geometry/two_view_geometry.h"
#include "tests/testing/synthetic.h"

namespace flysfm {
namespace {

// A 24 MP photo's camera, its principal point off the centre as real
// lenses have it.
// The longer side of the test photos.
constexpr int kWidth = 6000;

Camera PhotoCamera(double focal_length) {
  Camera camera = Camera::FromFocal(CameraModelId::kPinhole, focal_length, kWidth, 4000);
  camera.params[2] += 40;
  camera.params[3] -= 25;
  return camera;
}

// A second view of a photographer's kind: a step of about a fifth of the
// distance to the scene, turned by up to 15 deg about a random axis, so that
// the two optical axes pass each other without meeting.
Rigid3d RandomStep(std::mt19937& rng) {
  std::uniform_real_distribution<double> angle(3, 15);
  const Eigen::Quaterniond rotation = testing::RandomRotationOfAngle(rng, angle(rng));
  return Rigid3d(rotation, testing::RandomUnitVector(rng));
}

Eigen::Matrix3d ExactFundamental(const Camera& camera, const Rigid3d& cam2_from_cam1) {
  const Eigen::Matrix3d K = CalibrationMatrix(camera);
  return FundamentalFromEssential(EssentialFromPose(cam2_from_cam1), K, K);
}

// F by the eight-point algorithm from `num_points` points 4-8 units in front
// of camera 1 seen in both images, each pixel with Gaussian noise.
Eigen::Matrix3d NoisyFundamental(const Camera& camera, const Rigid3d& cam2_from_cam1,
                                 double noise_px, int num_points, std::mt19937& rng) {
  std::uniform_real_distribution<double> lateral(-2.5, 2.5), depth(4, 8);
  std::normal_distribution<double> noise(0, noise_px);
  std::vector<Eigen::Vector2d> points1, points2;
  const auto inside = [&](const Eigen::Vector2d& pixel) {
    return pixel.x() >= 0 && pixel.y() >= 0 && pixel.x() < camera.width &&
           pixel.y() < camera.height;
  };
  while (int(points1.size()) < num_points) {
    const Eigen::Vector3d point(lateral(rng), lateral(rng), depth(rng));
    const Eigen::Vector3d in_cam2 = cam2_from_cam1 * point;
    if (in_cam2.z() <= 0) continue;
    const Eigen::Vector2d pixel1 = camera.ImgFromCam(point);
    const Eigen::Vector2d pixel2 = camera.ImgFromCam(in_cam2);
    if (!inside(pixel1) || !inside(pixel2)) continue;
    points1.push_back(pixel1 + Eigen::Vector2d(noise(rng), noise(rng)));
    points2.push_back(pixel2 + Eigen::Vector2d(noise(rng), noise(rng)));
  }
  const std::vector<Eigen::Matrix3d> F = FundamentalFromEightPoints(points1, points2);
  REQUIRE(F.size() == 1);
  return F[0];
}

Eigen::Vector2d PrincipalPoint(const Camera& camera) {
  return {camera.params[2], camera.params[3]};
}

TEST_CASE("The singular-value gap vanishes at the true focal length only") {
  std::mt19937 rng(1);
  const Camera camera = PhotoCamera(5000);
  for (int trial = 0; trial < 20; ++trial) {
    const Eigen::Matrix3d F = ExactFundamental(camera, RandomStep(rng));
    CHECK(EssentialSingularValueGap(F, PrincipalPoint(camera), 5000) < 1e-9);
    CHECK(EssentialSingularValueGap(F, PrincipalPoint(camera), 2500) > 1e-3);
  }
}

// A pair turned by a few degrees about an axis near its baseline's
// constrains f only weakly (the gap rises by less than 1e-3 at 25 % off):
// such a pair may give no estimate.
TEST_CASE("Exact F of one pair gives its focal length, from 0.4 to 4 times the image width") {
  std::mt19937 rng(2);
  FocalFromFundamentalOptions options;
  int estimated = 0;
  for (const double focal : {2400.0, 5000.0, 12000.0, 24000.0}) {
    const Camera camera = PhotoCamera(focal);
    for (int trial = 0; trial < 10; ++trial) {
      const Eigen::Matrix3d F = ExactFundamental(camera, RandomStep(rng));
      double estimate = 0;
      if (FocalFromFundamentals({F}, PrincipalPoint(camera), kWidth, 2 * focal, options,
                                &estimate) == 0) {
        continue;
      }
      ++estimated;
      CHECK(std::abs(estimate / focal - 1) < 1e-6);
    }
  }
  CHECK(estimated >= 36);
}

// With half a pixel of noise and 200 matches, a single pair of a 24 MP photo
// fixes its focal length to a few per cent; three pairs, as the first photos
// of a session give, to within the 5 % the engine asks of a self-calibration.
TEST_CASE("Three noisy pairs: the focal length within 5 %, or no estimate") {
  std::mt19937 rng(3);
  FocalFromFundamentalOptions options;
  int estimated = 0, within = 0;
  const double focal = 4500;
  const Camera camera = PhotoCamera(focal);
  for (int trial = 0; trial < 100; ++trial) {
    std::vector<Eigen::Matrix3d> fundamentals;
    for (int pair = 0; pair < 3; ++pair) {
      fundamentals.push_back(NoisyFundamental(camera, RandomStep(rng), 0.5, 200, rng));
    }
    double estimate = 0;
    if (FocalFromFundamentals(fundamentals, PrincipalPoint(camera), kWidth, 1.44 * focal, options,
                              &estimate) == 0) {
      continue;
    }
    ++estimated;
    within += std::abs(estimate / focal - 1) <= 0.05;
  }
  CHECK(estimated >= 90);
  CHECK(within == estimated);
}

// Camera 2 on a circle around the point `distance` ahead of camera 1, looking
// at it: the two optical axes meet (a turntable, a walk around a statue aimed
// at its centre).
Rigid3d FixatingStep(double angle_deg, double distance, std::mt19937& rng) {
  const Eigen::Vector3d target(0, 0, distance);
  const Eigen::Vector3d axis = testing::RandomUnitVector(rng).cross(Eigen::Vector3d::UnitZ());
  const Eigen::Matrix3d world_from_cam2 =
      Eigen::AngleAxisd(angle_deg * M_PI / 180, axis.normalized()).toRotationMatrix();
  const Eigen::Vector3d center2 = target - world_from_cam2 * Eigen::Vector3d(0, 0, distance);
  return Rigid3d(Eigen::Matrix3d(world_from_cam2.transpose()),
                 -world_from_cam2.transpose() * center2);
}

// F then holds for every focal length: no estimate is the only right answer.
TEST_CASE("Optical axes that meet: no estimate, exact or with noise") {
  std::mt19937 rng(4);
  const Camera camera = PhotoCamera(5000);
  FocalFromFundamentalOptions options;
  for (int trial = 0; trial < 20; ++trial) {
    const Eigen::Matrix3d F = ExactFundamental(camera, FixatingStep(5 + trial, 6, rng));
    double estimate = 0;
    CHECK(FocalFromFundamentals({F}, PrincipalPoint(camera), kWidth, 10000, options,
                                &estimate) == 0);
  }
  int estimated = 0;
  for (int trial = 0; trial < 100; ++trial) {
    std::vector<Eigen::Matrix3d> fundamentals;
    for (int pair = 0; pair < 3; ++pair) {
      fundamentals.push_back(
          NoisyFundamental(camera, FixatingStep(5 + trial % 20, 6, rng), 0.5, 200, rng));
    }
    double estimate = 0;
    estimated +=
        FocalFromFundamentals(fundamentals, PrincipalPoint(camera), kWidth, 10000, options,
                              &estimate);
  }
  // A false estimate needs the noise to carve a minimum three times deeper
  // than its sides at 25 % off.
  CHECK(estimated <= 5);
}

TEST_CASE("No F, a non-finite F, no image size or bad options: no estimate") {
  double estimate = -1;
  FocalFromFundamentalOptions options;
  CHECK(FocalFromFundamentals({}, Eigen::Vector2d::Zero(), kWidth, 1000, options, &estimate) == 0);
  Eigen::Matrix3d bad = Eigen::Matrix3d::Identity();
  bad(0, 1) = std::numeric_limits<double>::quiet_NaN();
  CHECK(FocalFromFundamentals({bad}, Eigen::Vector2d::Zero(), kWidth, 1000, options,
                              &estimate) == 0);
  CHECK(FocalFromFundamentals({Eigen::Matrix3d::Zero()}, Eigen::Vector2d::Zero(), kWidth, 1000,
                              options, &estimate) == 0);
  std::mt19937 rng(5);
  const Camera camera = PhotoCamera(5000);
  const Eigen::Matrix3d F = ExactFundamental(camera, RandomStep(rng));
  CHECK(FocalFromFundamentals({F}, PrincipalPoint(camera), kWidth, 0, options, &estimate) == 0);
  CHECK(FocalFromFundamentals({F}, PrincipalPoint(camera), 0, 10000, options, &estimate) == 0);
  options.max_focal_length_factor = options.min_focal_length_factor;
  CHECK_FALSE(options.Check());
  CHECK(FocalFromFundamentals({F}, PrincipalPoint(camera), kWidth, 10000, options, &estimate) == 0);
  CHECK(estimate == -1);
}

}  // namespace
}  // namespace flysfm
