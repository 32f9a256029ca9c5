#include "geometry/homography_matrix.h"

#include <cmath>

#include <catch2/catch.hpp>

#include "geometry/fundamental_matrix.h"
#include "geometry/two_view_geometry.h"
#include "tests/testing/two_view_matches.h"

namespace flysfm {
namespace {

// The homography induced by the world plane z = 0 (planar scenes).
Eigen::Matrix3d TrueHomography(const testing::TwoViewMatches& matches) {
  const Eigen::Matrix3d K = CalibrationMatrix(matches.camera);
  auto plane_to_image = [&](const Rigid3d& cam_from_world) {
    const Matrix3x4d P = cam_from_world.ToMatrix();
    Eigen::Matrix3d M;
    M << P.col(0), P.col(1), P.col(3);
    return Eigen::Matrix3d(K * M);
  };
  return plane_to_image(matches.cam2_from_world) *
         plane_to_image(matches.cam1_from_world).inverse();
}

testing::TwoViewMatches PlanarInstance(int seed, int num_matches) {
  testing::TwoViewMatchesOptions options;
  options.scene = testing::TwoViewScene::kPlanar;
  options.num_matches = num_matches;
  options.seed = seed;
  options.arc_deg = 5 + seed % 40;
  return testing::MakeTwoViewMatches(options);
}

TEST_CASE("The DLT recovers H exactly on 500 random planar scenes") {
  for (int seed = 0; seed < 500; ++seed) {
    const auto matches = PlanarInstance(seed, 4 + (seed % 2) * (seed % 60));
    const auto models = HomographyFromPoints(matches.points1, matches.points2);
    REQUIRE(models.size() == 1);
    CHECK(ProjectiveMatrixDistance(models[0], TrueHomography(matches)) < 1e-6);
    for (std::size_t i = 0; i < matches.points1.size(); ++i) {
      CHECK(HomographyTransferError(models[0], matches.points1[i], matches.points2[i]) <
            1e-12);
    }
  }
}

TEST_CASE("Homography solver returns nothing for degenerate input") {
  const auto matches = PlanarInstance(7, 6);
  const auto& p1 = matches.points1;
  const auto& p2 = matches.points2;
  CHECK(HomographyFromPoints({p1.begin(), p1.begin() + 3},
                             {p2.begin(), p2.begin() + 3}).empty());
  CHECK(HomographyFromPoints(p1, {p2.begin(), p2.begin() + 5}).empty());
  auto bad = p1;
  bad[1].y() = std::numeric_limits<double>::quiet_NaN();
  CHECK(HomographyFromPoints(bad, p2).empty());
  // Three of four points collinear in both images.
  std::vector<Eigen::Vector2d> q1 = {{0, 0}, {100, 50}, {200, 100}, {30, 300}};
  std::vector<Eigen::Vector2d> q2 = {{10, 5}, {90, 60}, {170, 115}, {60, 280}};
  CHECK(HomographyFromPoints(q1, q2).empty());
  // Collinear in image 1 only: the homography would be singular.
  std::vector<Eigen::Vector2d> r2 = {{10, 5}, {90, 60}, {200, 40}, {60, 280}};
  CHECK(HomographyFromPoints(q1, r2).empty());
  // All points the same, or repeated.
  CHECK(HomographyFromPoints(std::vector<Eigen::Vector2d>(4, p1[0]),
                             std::vector<Eigen::Vector2d>(4, p2[0])).empty());
  CHECK(HomographyFromPoints({p1[0], p1[1], p1[0], p1[1]},
                             {p2[0], p2[1], p2[0], p2[1]}).empty());
}

TEST_CASE("The Sampson error of H approximates the 4D distance to the model") {
  const auto matches = PlanarInstance(11, 30);
  const Eigen::Matrix3d H = TrueHomography(matches);
  for (std::size_t i = 0; i < matches.points1.size(); ++i) {
    CHECK(HomographySampsonError(H, matches.points1[i], matches.points2[i]) < 1e-16);
    // Moving x2 by d with x1 fixed: the nearest exact pair is at most |d|
    // away in 4D, and, as H is near a similarity here, not much closer.
    const Eigen::Vector2d moved = matches.points2[i] + Eigen::Vector2d(0.6, -0.8);
    const double e = std::sqrt(HomographySampsonError(H, matches.points1[i], moved));
    CHECK(e <= 1.0 + 1e-6);
    CHECK(e > 0.3);
  }
}

}  // namespace
}  // namespace flysfm
