#include "geometry/fundamental_matrix.h"

#include <cmath>

#include <catch2/catch.hpp>

#include "geometry/essential_matrix.h"
#include "geometry/two_view_geometry.h"
#include "tests/testing/two_view_matches.h"

namespace flysfm {
namespace {

Eigen::Matrix3d TrueFundamental(const testing::TwoViewMatches& matches) {
  const Eigen::Matrix3d K = CalibrationMatrix(matches.camera);
  return FundamentalFromEssential(EssentialFromPose(matches.Cam2FromCam1()), K, K);
}

double BestDistance(const std::vector<Eigen::Matrix3d>& models,
                    const Eigen::Matrix3d& truth) {
  double best = std::numeric_limits<double>::infinity();
  for (const auto& model : models) best = std::min(best, ProjectiveMatrixDistance(model, truth));
  return best;
}

testing::TwoViewMatches Instance(int seed, int num_matches) {
  testing::TwoViewMatchesOptions options;
  options.num_matches = num_matches;
  options.seed = seed;
  options.arc_deg = 5 + seed % 40;
  return testing::MakeTwoViewMatches(options);
}

TEST_CASE("The 7-point algorithm recovers F exactly on 500 random scenes") {
  int solved = 0;
  for (int seed = 0; seed < 500; ++seed) {
    const auto matches = Instance(seed, 7);
    REQUIRE(matches.points1.size() == 7);
    const auto models = FundamentalFromSevenPoints(matches.points1, matches.points2);
    REQUIRE(!models.empty());
    REQUIRE(models.size() <= 3);
    CHECK(BestDistance(models, TrueFundamental(matches)) < 1e-6);
    for (const auto& F : models) {
      CHECK(std::abs(F.determinant()) < 1e-9);
      for (int i = 0; i < 7; ++i) {
        CHECK(FundamentalSampsonError(F, matches.points1[i], matches.points2[i]) < 1e-12);
      }
    }
    ++solved;
  }
  CHECK(solved == 500);
}

TEST_CASE("The 8-point algorithm recovers F exactly on 500 random scenes") {
  for (int seed = 0; seed < 500; ++seed) {
    const auto matches = Instance(1000 + seed, 8 + seed % 50);
    const auto models = FundamentalFromEightPoints(matches.points1, matches.points2);
    REQUIRE(models.size() == 1);
    CHECK(BestDistance(models, TrueFundamental(matches)) < 1e-6);
    CHECK(std::abs(models[0].determinant()) < 1e-12);
  }
}

TEST_CASE("Fundamental solvers return nothing for degenerate input") {
  const auto matches = Instance(3, 8);
  std::vector<Eigen::Vector2d> p1 = matches.points1, p2 = matches.points2;
  // Too few points, unequal sizes.
  CHECK(FundamentalFromSevenPoints({p1.begin(), p1.begin() + 6},
                                   {p2.begin(), p2.begin() + 6}).empty());
  CHECK(FundamentalFromEightPoints({p1.begin(), p1.begin() + 7},
                                   {p2.begin(), p2.begin() + 7}).empty());
  CHECK(FundamentalFromEightPoints(p1, {p2.begin(), p2.begin() + 7}).empty());
  CHECK(FundamentalFromSevenPoints({}, {}).empty());
  // NaN and infinity.
  auto bad = p1;
  bad[2].x() = std::numeric_limits<double>::quiet_NaN();
  CHECK(FundamentalFromEightPoints(bad, p2).empty());
  CHECK(FundamentalFromSevenPoints({bad.begin(), bad.begin() + 7},
                                   {p2.begin(), p2.begin() + 7}).empty());
  bad[2].x() = std::numeric_limits<double>::infinity();
  CHECK(FundamentalFromEightPoints(bad, p2).empty());
  // Collinear points in both images.
  std::vector<Eigen::Vector2d> line1, line2;
  for (int i = 0; i < 8; ++i) {
    line1.emplace_back(10.0 + 30 * i, 20.0 + 10 * i);
    line2.emplace_back(50.0 + 25 * i, 5.0 + 20 * i);
  }
  CHECK(FundamentalFromEightPoints(line1, line2).empty());
  CHECK(FundamentalFromSevenPoints({line1.begin(), line1.begin() + 7},
                                   {line2.begin(), line2.begin() + 7}).empty());
  // All points identical, and repeated matches leaving too few distinct ones.
  CHECK(FundamentalFromEightPoints(std::vector<Eigen::Vector2d>(8, p1[0]),
                                   std::vector<Eigen::Vector2d>(8, p2[0])).empty());
  auto dup1 = p1, dup2 = p2;
  for (int i = 4; i < 8; ++i) {
    dup1[i] = p1[i - 4];
    dup2[i] = p2[i - 4];
  }
  CHECK(FundamentalFromEightPoints(dup1, dup2).empty());
  CHECK(FundamentalFromSevenPoints({dup1.begin(), dup1.begin() + 7},
                                   {dup2.begin(), dup2.begin() + 7}).empty());
}

TEST_CASE("The Sampson error of F is the squared distance to the epipolar line "
          "for a point moved in one image only") {
  const auto matches = Instance(5, 20);
  const Eigen::Matrix3d F = TrueFundamental(matches);
  for (int i = 0; i < 20; ++i) {
    const Eigen::Vector3d line = F * matches.points1[i].homogeneous();
    const Eigen::Vector2d normal = line.head<2>().normalized();
    const Eigen::Vector2d moved = matches.points2[i] + 0.3 * normal;
    // Moving x2 off its line by 0.3 px, while x1 stays: the first-order 4D
    // distance is at most that and at least its share along the line normal.
    const double e = std::sqrt(FundamentalSampsonError(F, matches.points1[i], moved));
    CHECK(e <= 0.3 + 1e-9);
    CHECK(e > 0.05);
    CHECK(FundamentalSampsonError(F, matches.points1[i], matches.points2[i]) < 1e-16);
  }
}

}  // namespace
}  // namespace flysfm
