#include "geometry/absolute_pose.h"

#include <cmath>

#include <catch2/catch.hpp>

#include "tests/testing/synthetic.h"

namespace flysfm {
namespace {

struct PoseInstance {
  Rigid3d cam_from_world;
  std::vector<Eigen::Vector2d> points2D;  // normalized
  std::vector<Eigen::Vector3d> points3D;
};

// A random pose anywhere, and points in front of it within a 60 degree field
// of view at depths 1 to 10.
PoseInstance RandomInstance(std::mt19937& rng, int num_points) {
  std::uniform_real_distribution<double> unit(-1, 1);
  std::uniform_real_distribution<double> depth(1, 10);
  PoseInstance instance;
  instance.cam_from_world =
      Rigid3d(testing::RandomRotation(rng), 5 * testing::RandomUnitVector(rng));
  const Rigid3d world_from_cam = Inverse(instance.cam_from_world);
  for (int i = 0; i < num_points; ++i) {
    const Eigen::Vector2d x(0.6 * unit(rng), 0.6 * unit(rng));
    const Eigen::Vector3d in_cam = depth(rng) * x.homogeneous();
    instance.points2D.push_back(x);
    instance.points3D.push_back(world_from_cam * in_cam);
  }
  return instance;
}

double PoseError(const Rigid3d& estimate, const Rigid3d& truth) {
  const double rotation = (estimate.rotation.toRotationMatrix() -
                           truth.rotation.toRotationMatrix()).norm();
  const double translation = (estimate.translation - truth.translation).norm() /
                             std::max(1.0, truth.translation.norm());
  return std::max(rotation, translation);
}

double BestPoseError(const std::vector<Rigid3d>& poses, const Rigid3d& truth) {
  double best = std::numeric_limits<double>::infinity();
  for (const auto& pose : poses) best = std::min(best, PoseError(pose, truth));
  return best;
}

TEST_CASE("P3P recovers the pose exactly on 500 random instances") {
  std::mt19937 rng(1);
  for (int instance = 0; instance < 500; ++instance) {
    const PoseInstance p = RandomInstance(rng, 3);
    const std::vector<Rigid3d> poses = P3P(p.points2D, p.points3D);
    REQUIRE(!poses.empty());
    REQUIRE(poses.size() <= 4);
    CHECK(BestPoseError(poses, p.cam_from_world) < 1e-6);
    for (const auto& pose : poses) {
      for (int i = 0; i < 3; ++i) {
        CHECK(((pose * p.points3D[i]).hnormalized() - p.points2D[i]).norm() < 1e-6);
      }
    }
  }
}

TEST_CASE("EPnP recovers the pose exactly on 500 random instances") {
  std::mt19937 rng(2);
  for (int instance = 0; instance < 500; ++instance) {
    const PoseInstance p = RandomInstance(rng, 4 + instance % 100);
    const std::vector<Rigid3d> poses = EPnP(p.points2D, p.points3D);
    REQUIRE(poses.size() == 1);
    CHECK(PoseError(poses[0], p.cam_from_world) < 1e-6);
  }
}

TEST_CASE("RefineAbsolutePose converges to the exact pose from a perturbed one") {
  std::mt19937 rng(3);
  for (int instance = 0; instance < 100; ++instance) {
    const PoseInstance p = RandomInstance(rng, 30);
    Rigid3d pose(testing::RandomRotationOfAngle(rng, 3.0) * p.cam_from_world.rotation,
                 p.cam_from_world.translation + 0.1 * testing::RandomUnitVector(rng));
    REQUIRE(RefineAbsolutePose(p.points2D, p.points3D, {}, &pose));
    CHECK(PoseError(pose, p.cam_from_world) < 1e-8);
  }
}

TEST_CASE("Absolute pose solvers return nothing for degenerate input") {
  std::mt19937 rng(4);
  const PoseInstance p = RandomInstance(rng, 6);
  const auto& x = p.points2D;
  const auto& X = p.points3D;
  CHECK(P3P({x[0], x[1]}, {X[0], X[1]}).empty());
  CHECK(EPnP({x[0], x[1], x[2]}, {X[0], X[1], X[2]}).empty());
  CHECK(EPnP(x, {X.begin(), X.begin() + 5}).empty());
  auto bad = X;
  bad[1].z() = std::numeric_limits<double>::quiet_NaN();
  CHECK(P3P({x[0], x[1], x[2]}, {bad[0], bad[1], bad[2]}).empty());
  CHECK(EPnP(x, bad).empty());
  // Collinear world points, repeated world points, repeated rays.
  const Eigen::Vector3d d = Eigen::Vector3d(1, 2, 3).normalized();
  CHECK(P3P({x[0], x[1], x[2]}, {X[0], X[0] + d, X[0] + 2 * d}).empty());
  CHECK(P3P({x[0], x[1], x[2]}, {X[0], X[0], X[2]}).empty());
  CHECK(P3P({x[0], x[0], x[2]}, {X[0], X[1], X[2]}).empty());
  std::vector<Eigen::Vector3d> line;
  for (int i = 0; i < 6; ++i) line.push_back(X[0] + i * d);
  CHECK(EPnP(x, line).empty());
  CHECK(EPnP(x, std::vector<Eigen::Vector3d>(6, X[0])).empty());
  // Coplanar points: EPnP's four control points are undetermined.
  std::vector<Eigen::Vector3d> plane;
  for (int i = 0; i < 6; ++i) plane.emplace_back(i, (i * i) % 5, 0);
  CHECK(EPnP(x, plane).empty());
  Rigid3d pose;
  CHECK(!RefineAbsolutePose({x[0], x[1]}, {X[0], X[1]}, {}, &pose));
}

TEST_CASE("EstimateAbsolutePose: 0.5 px noise and 40 % outliers") {
  const Camera camera = Camera::FromFocal(CameraModelId::kPinhole, 500, 640, 480);
  std::mt19937 rng(5);
  std::normal_distribution<double> noise(0, 0.5);
  std::uniform_real_distribution<double> unit(0, 1);
  for (int trial = 0; trial < 20; ++trial) {
    const PoseInstance p = RandomInstance(rng, 500);
    std::vector<Eigen::Vector2d> pixels;
    std::vector<char> truth;
    for (std::size_t i = 0; i < p.points2D.size(); ++i) {
      if (i % 5 < 2) {  // 40 %
        pixels.emplace_back(unit(rng) * camera.width, unit(rng) * camera.height);
        truth.push_back(0);
      } else {
        pixels.push_back(camera.ImgFromCam(p.points2D[i].homogeneous()) +
                         Eigen::Vector2d(noise(rng), noise(rng)));
        truth.push_back(1);
      }
    }
    AbsolutePoseOptions options;
    options.ransac.seed = trial;
    const AbsolutePoseResult result = EstimateAbsolutePose(camera, pixels, p.points3D, options);
    REQUIRE(result.success);
    CHECK(RotationDifferenceDeg(result.cam_from_world, p.cam_from_world) < 0.5);
    int agree = 0;
    for (std::size_t i = 0; i < truth.size(); ++i) agree += result.inlier_mask[i] == truth[i];
    CHECK(agree > 0.95 * truth.size());
  }
}

TEST_CASE("EstimateAbsolutePose handles planar scenes and bad input") {
  const Camera camera = Camera::FromFocal(CameraModelId::kSimpleRadial, 400, 640, 480);
  std::mt19937 rng(6);
  std::uniform_real_distribution<double> uniform(-1, 1);
  const Rigid3d cam_from_world(testing::RandomRotationOfAngle(rng, 10),
                               Eigen::Vector3d(0.1, -0.2, 4));
  std::vector<Eigen::Vector3d> points;
  std::vector<Eigen::Vector2d> pixels;
  for (int i = 0; i < 100; ++i) {
    points.emplace_back(uniform(rng), uniform(rng), 0.0);
    pixels.push_back(camera.ImgFromCam(cam_from_world * points.back()));
  }
  AbsolutePoseOptions options;
  AbsolutePoseResult result = EstimateAbsolutePose(camera, pixels, points, options);
  REQUIRE(result.success);
  CHECK(result.num_inliers == 100);
  CHECK(PoseError(result.cam_from_world, cam_from_world) < 1e-6);

  // NaN correspondences are never inliers; too few points or bad options fail
  // cleanly.
  pixels[3].x() = std::numeric_limits<double>::quiet_NaN();
  points[7].y() = std::numeric_limits<double>::infinity();
  result = EstimateAbsolutePose(camera, pixels, points, options);
  REQUIRE(result.success);
  CHECK(!result.inlier_mask[3]);
  CHECK(!result.inlier_mask[7]);
  CHECK(result.num_inliers == 98);
  CHECK(!EstimateAbsolutePose(camera, {pixels.begin(), pixels.begin() + 5},
                              {points.begin(), points.begin() + 5}, options).success);
  CHECK(!EstimateAbsolutePose(camera, pixels, {points.begin(), points.begin() + 50},
                              options).success);
  options.max_error_px = -1;
  CHECK(!options.Check());
  CHECK_THROWS_AS(EstimateAbsolutePose(camera, pixels, points, options),
                  std::invalid_argument);
}

TEST_CASE("ReestimateAbsolutePose keeps the first pose, with a mask over every correspondence, "
          "when RANSAC fails on the longer list") {
  std::mt19937 rng(7);
  const Camera camera = Camera::FromFocal(CameraModelId::kPinhole, 500, 640, 480);
  const PoseInstance p = RandomInstance(rng, 40);
  std::vector<Eigen::Vector2d> pixels;
  for (const Eigen::Vector2d& x : p.points2D) pixels.push_back(camera.ImgFromCam(x.homogeneous()));
  std::vector<Eigen::Vector3d> points = p.points3D;
  // Densification appends 30 correspondences, every one wrong by 50 px.
  for (int i = 0; i < 30; ++i) {
    pixels.push_back(pixels[i] + Eigen::Vector2d(50, 0));
    points.push_back(p.points3D[i]);
  }
  AbsolutePoseOptions options;
  AbsolutePoseResult result =
      ReestimateAbsolutePose(camera, pixels, points, p.cam_from_world, options);
  REQUIRE(result.success);
  REQUIRE(result.inlier_mask.size() == pixels.size());
  CHECK(result.num_inliers == 40);
  CHECK(PoseError(result.cam_from_world, p.cam_from_world) < 1e-6);

  // More inliers demanded than the longer list has: RANSAC fails, the first
  // pose stays, and its inliers are counted over all 70 correspondences.
  options.min_num_inliers = 45;
  const Rigid3d first(p.cam_from_world.rotation, p.cam_from_world.translation);
  result = ReestimateAbsolutePose(camera, pixels, points, first, options);
  REQUIRE(result.success);
  REQUIRE(result.inlier_mask.size() == pixels.size());
  CHECK(result.num_inliers == 40);
  for (std::size_t i = 0; i < pixels.size(); ++i) CHECK(bool(result.inlier_mask[i]) == (i < 40));
  CHECK(PoseError(result.cam_from_world, first) == 0);
}

}  // namespace
}  // namespace flysfm
