#include "geometry/triangulation.h"

#include <cmath>

#include <catch2/catch.hpp>

#include "tests/testing/synthetic.h"

namespace flysfm {
namespace {

// Random cameras looking at a random point from 2 to 10 units away.
struct Views {
  std::vector<Matrix3x4d> cams_from_world;
  std::vector<Eigen::Vector2d> points;
  Eigen::Vector3d point;
};

Views RandomViews(std::mt19937& rng, int num_views) {
  std::uniform_real_distribution<double> distance(2, 10);
  Views views;
  views.point = 3 * testing::RandomUnitVector(rng);
  for (int i = 0; i < num_views; ++i) {
    const Eigen::Vector3d center = views.point + distance(rng) * testing::RandomUnitVector(rng);
    // Look at the point, with a random roll and up to 15 degrees off-axis.
    const Eigen::Vector3d forward = (views.point - center).normalized();
    const Eigen::Quaterniond look =
        Eigen::Quaterniond::FromTwoVectors(forward, Eigen::Vector3d::UnitZ());
    const Eigen::Quaterniond rotation =
        testing::RandomRotationOfAngle(rng, 15) * look;
    const Rigid3d cam_from_world(rotation, -(rotation * center));
    views.cams_from_world.push_back(cam_from_world.ToMatrix());
    views.points.push_back((cam_from_world * views.point).hnormalized());
  }
  return views;
}

TEST_CASE("Two-view DLT triangulates exactly on 500 random instances") {
  std::mt19937 rng(1);
  for (int instance = 0; instance < 500; ++instance) {
    const Views v = RandomViews(rng, 2);
    const auto point = TriangulatePoint(v.cams_from_world[0], v.cams_from_world[1],
                                        v.points[0], v.points[1]);
    REQUIRE(point);
    CHECK((*point - v.point).norm() < 1e-6 * std::max(1.0, v.point.norm()));
    CHECK(HasPositiveDepth(v.cams_from_world[0], *point));
  }
}

TEST_CASE("Multi-view DLT triangulates exactly on 500 random instances") {
  std::mt19937 rng(2);
  for (int instance = 0; instance < 500; ++instance) {
    const Views v = RandomViews(rng, 2 + instance % 10);
    const auto point = TriangulateMultiViewPoint(v.cams_from_world, v.points);
    REQUIRE(point);
    CHECK((*point - v.point).norm() < 1e-6 * std::max(1.0, v.point.norm()));
  }
}

TEST_CASE("Triangulation returns nothing for degenerate input") {
  std::mt19937 rng(3);
  const Views v = RandomViews(rng, 2);
  // Zero baseline: the same camera twice.
  CHECK(!TriangulatePoint(v.cams_from_world[0], v.cams_from_world[0], v.points[0],
                          v.points[0]));
  // Parallel rays from two centres: a point at infinity.
  Matrix3x4d shifted = v.cams_from_world[0];
  shifted.col(3) += Eigen::Vector3d(1, 0, 0);
  CHECK(!TriangulatePoint(v.cams_from_world[0], shifted, v.points[0], v.points[0]));
  Eigen::Vector2d nan_point = v.points[1];
  nan_point.x() = std::numeric_limits<double>::quiet_NaN();
  CHECK(!TriangulatePoint(v.cams_from_world[0], v.cams_from_world[1], v.points[0], nan_point));
  CHECK(!TriangulateMultiViewPoint({v.cams_from_world[0]}, {v.points[0]}));
  CHECK(!TriangulateMultiViewPoint(v.cams_from_world, {v.points[0]}));
}

TEST_CASE("TriangulationAngleDeg measures the angle between the rays") {
  const Eigen::Vector3d point(0, 0, 0);
  CHECK(TriangulationAngleDeg({1, 0, 0}, {0, 1, 0}, point) == Approx(90));
  CHECK(TriangulationAngleDeg({1, 0, 0}, {2, 0, 0}, point) == Approx(0).margin(1e-12));
  CHECK(TriangulationAngleDeg({1, 0, 0}, {1, std::sqrt(3.0), 0}, point) == Approx(60));
}

std::vector<TriangulationObservation> Observe(const testing::SyntheticScene& scene, int point) {
  std::vector<TriangulationObservation> observations;
  for (const auto& obs : scene.observations) {
    if (obs.point != point) continue;
    observations.push_back({scene.cams_from_world[obs.image], &scene.camera, obs.pixel});
  }
  return observations;
}

TEST_CASE("EstimateTriangulation rejects outlier observations") {
  testing::SyntheticSceneOptions options;
  options.num_images = 12;
  options.num_points = 50;
  options.noise_px = 0.5;
  options.camera_distance = 4;
  options.camera = Camera::FromString("OPENCV 450,455,320,240,-0.1,0.02,0.001,-0.001", 640, 480);
  const testing::SyntheticScene scene = testing::MakeSyntheticScene(options);
  std::mt19937 rng(4);
  std::uniform_real_distribution<double> unit(0, 1);
  TriangulationOptions triangulation;
  for (int p = 0; p < options.num_points; ++p) {
    auto observations = Observe(scene, p);
    if (observations.size() < 8) continue;
    // A third of the observations (rounded down) become random pixels.
    std::vector<char> truth(observations.size(), 1);
    for (std::size_t k = 0; k < observations.size() / 3; ++k) {
      observations[3 * k + 1].pixel = Eigen::Vector2d(unit(rng) * 640, unit(rng) * 480);
      truth[3 * k + 1] = 0;
    }
    const TriangulationResult result = EstimateTriangulation(observations, triangulation);
    REQUIRE(result.success);
    // Reprojection error is measured in pixels; random pixels are far off.
    for (std::size_t k = 0; k < truth.size(); ++k) CHECK(result.inlier_mask[k] == truth[k]);
    // 0.5 px noise at 3 to 5 units with a 450 px focal moves a single ray by
    // about 0.005 units; over 60 degrees of views the point is determined to
    // within a few of those.
    CHECK((result.point - scene.points[p]).norm() < 0.03);
  }
}

TEST_CASE("EstimateTriangulation needs a triangulation angle and cheirality") {
  const Camera camera = Camera::FromFocal(CameraModelId::kSimplePinhole, 500, 640, 480);
  const Eigen::Vector3d point(0.2, -0.1, 5.0);
  // Three cameras 1 cm apart looking at a point 5 units away: rays within
  // about 0.1 degrees.
  std::vector<TriangulationObservation> observations;
  for (int i = 0; i < 3; ++i) {
    const Rigid3d cam_from_world(Eigen::Quaterniond::Identity(),
                                 Eigen::Vector3d(-0.01 * i, 0.005 * i, 0));
    observations.push_back({cam_from_world, &camera,
                            camera.ImgFromCam(cam_from_world * point)});
  }
  TriangulationOptions triangulation;
  triangulation.min_tri_angle_deg = 1.0;
  CHECK(!EstimateTriangulation(observations, triangulation).success);
  triangulation.min_tri_angle_deg = 0;
  TriangulationResult result = EstimateTriangulation(observations, triangulation);
  REQUIRE(result.success);
  CHECK((result.point - point).norm() < 1e-6);

  // A point behind every camera is never accepted.
  std::vector<TriangulationObservation> behind;
  for (int i = 0; i < 3; ++i) {
    const Rigid3d cam_from_world(Eigen::Quaterniond::Identity(),
                                 Eigen::Vector3d(-1.0 * i, 0, 0));
    const Eigen::Vector3d in_cam = cam_from_world * Eigen::Vector3d(0.2, 0.1, -5.0);
    // The pixel where the mirrored point (in front) would project.
    behind.push_back({cam_from_world, &camera, camera.ImgFromCam(-in_cam)});
  }
  result = EstimateTriangulation(behind, triangulation);
  if (result.success) {
    for (const auto& obs : behind) CHECK((obs.cam_from_world * result.point).z() > 0);
  }

  // Observations without a camera or with NaN pixels never count; bad
  // options throw.
  observations[0].camera = nullptr;
  observations[1].pixel.x() = std::numeric_limits<double>::quiet_NaN();
  observations.push_back(observations[2]);
  observations.back().cam_from_world.translation.x() += 1.0;
  observations.back().pixel = camera.ImgFromCam(observations.back().cam_from_world * point);
  result = EstimateTriangulation(observations, triangulation);
  REQUIRE(result.success);
  CHECK(!result.inlier_mask[0]);
  CHECK(!result.inlier_mask[1]);
  CHECK(result.num_inliers == 2);
  CHECK(!EstimateTriangulation({}, triangulation).success);
  triangulation.min_num_inliers = 1;
  CHECK(!triangulation.Check());
  CHECK_THROWS_AS(EstimateTriangulation(observations, triangulation), std::invalid_argument);
}

}  // namespace
}  // namespace flysfm
