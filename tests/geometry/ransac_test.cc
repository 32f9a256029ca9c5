#include "geometry/ransac.h"

#include <cmath>
#include <limits>
#include <random>

#include <Eigen/Dense>
#include <catch2/catch.hpp>

#include "geometry/essential_matrix.h"
#include "geometry/fundamental_matrix.h"
#include "geometry/two_view_geometry.h"
#include "tests/testing/two_view_matches.h"

namespace flysfm {
namespace {

TEST_CASE("RansacRequiredIterations follows log(1 - p) / log(1 - w^m)") {
  CHECK(RansacRequiredIterations(50, 100, 7, 0.99) == 588);
  CHECK(RansacRequiredIterations(60, 100, 5, 0.999) == 86);
  CHECK(RansacRequiredIterations(500, 1000, 3, 0.999) == 52);
  CHECK(RansacRequiredIterations(100, 100, 5, 0.999) == 1);
  CHECK(RansacRequiredIterations(0, 100, 5, 0.999) == std::numeric_limits<int>::max());
  CHECK(RansacRequiredIterations(1, 1000000, 8, 0.999) == std::numeric_limits<int>::max());
}

// A line y = a x + b through 2D points: the smallest estimator that
// exercises every part of the generic RANSAC.
class LineEstimator {
 public:
  using Model = Eigen::Vector2d;  // (a, b)
  static constexpr int kMinSampleSize = 2;
  explicit LineEstimator(const std::vector<Eigen::Vector2d>& points) : points_(points) {}
  int NumData() const { return static_cast<int>(points_.size()); }
  void MinimalSolve(const std::vector<int>& sample, std::vector<Model>* models) const {
    const Eigen::Vector2d& p = points_[sample[0]];
    const Eigen::Vector2d& q = points_[sample[1]];
    if (p.x() == q.x()) return;
    const double a = (q.y() - p.y()) / (q.x() - p.x());
    models->emplace_back(a, p.y() - a * p.x());
  }
  void NonMinimalSolve(const std::vector<int>& indices, const Model&,
                       std::vector<Model>* models) const {
    ++num_non_minimal;
    Eigen::MatrixXd A(indices.size(), 2);
    Eigen::VectorXd y(indices.size());
    for (std::size_t k = 0; k < indices.size(); ++k) {
      A.row(k) << points_[indices[k]].x(), 1.0;
      y(k) = points_[indices[k]].y();
    }
    models->push_back(A.colPivHouseholderQr().solve(y));
  }
  bool Refine(const std::vector<int>& inliers, Model* model) const {
    ++num_refinements;
    std::vector<Model> fits;
    NonMinimalSolve(inliers, *model, &fits);
    *model = fits[0];
    return true;
  }
  double SquaredError(const Model& m, int i) const {
    const double r = points_[i].y() - (m(0) * points_[i].x() + m(1));
    return r * r;
  }
  mutable int num_non_minimal = 0;
  mutable int num_refinements = 0;

 private:
  const std::vector<Eigen::Vector2d>& points_;
};

std::vector<Eigen::Vector2d> NoisyLine(int n, double outlier_ratio, std::vector<char>* truth) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> x(-10, 10), y(-30, 30);
  std::normal_distribution<double> noise(0, 0.1);
  std::vector<Eigen::Vector2d> points;
  truth->clear();
  for (int i = 0; i < n; ++i) {
    const double xi = x(rng);
    if (i < outlier_ratio * n) {
      points.emplace_back(xi, y(rng));
      truth->push_back(std::abs(points.back().y() - (2 * xi - 1)) < 0.5);
    } else {
      points.emplace_back(xi, 2 * xi - 1 + noise(rng));
      truth->push_back(1);
    }
  }
  return points;
}

TEST_CASE("Ransac fits a line through 60 % outliers, reproducibly per seed") {
  std::vector<char> truth;
  const auto points = NoisyLine(500, 0.6, &truth);
  const LineEstimator estimator(points);
  RansacOptions options;
  options.max_error = 0.5;
  options.seed = 3;
  const auto result = Ransac(estimator, options);
  REQUIRE(result.success);
  CHECK(result.model(0) == Approx(2).margin(0.01));
  CHECK(result.model(1) == Approx(-1).margin(0.02));
  // Outliers that happen to lie near the line may flip with the fit.
  CHECK(testing::InlierClassificationRate(result.inlier_mask, truth) > 0.99);
  CHECK(estimator.num_non_minimal > 0);  // LO ran
  CHECK(estimator.num_refinements > 0);
  // With 40 % inliers and samples of 2, ~40 samples reach 0.999.
  CHECK(result.num_iterations < 200);
  const auto again = Ransac(estimator, options);
  CHECK(again.model == result.model);
  CHECK(again.num_iterations == result.num_iterations);
  CHECK(again.inlier_mask == result.inlier_mask);
}

TEST_CASE("Ransac respects its options and fails cleanly") {
  std::vector<char> truth;
  const auto points = NoisyLine(100, 0.5, &truth);
  const LineEstimator estimator(points);
  RansacOptions options;
  options.max_error = 0.5;
  options.max_iterations = 3;
  options.local_optimization = false;
  options.final_refinement = false;
  const auto capped = Ransac(estimator, options);
  CHECK(capped.num_iterations <= 3);
  CHECK(estimator.num_non_minimal == 0);
  CHECK(estimator.num_refinements == 0);
  options.max_iterations = 1000;
  options.min_iterations = 500;
  CHECK(Ransac(estimator, options).num_iterations >= 500);

  const std::vector<Eigen::Vector2d> one_point = {{0, 0}};
  CHECK(!Ransac(LineEstimator(one_point), options).success);
  const std::vector<Eigen::Vector2d> vertical = {{1, 0}, {1, 1}, {1, 2}};
  CHECK(!Ransac(LineEstimator(vertical), options).success);

  using Change = void (*)(RansacOptions&);
  for (Change bad : std::vector<Change>{[](RansacOptions& o) { o.max_error = 0; },
                   [](RansacOptions& o) { o.max_error = std::nan(""); },
                   [](RansacOptions& o) { o.confidence = 1; },
                   [](RansacOptions& o) { o.max_iterations = 0; },
                   [](RansacOptions& o) { o.min_iterations = 2000; }}) {
    RansacOptions invalid = options;
    bad(invalid);
    CHECK(!invalid.Check());
    CHECK_THROWS_AS(Ransac(estimator, invalid), std::invalid_argument);
  }
}

// ---- The two-view estimators with 0.5 px noise and 40 % outliers. ----

testing::TwoViewMatches NoisyMatches(testing::TwoViewScene scene, int seed) {
  testing::TwoViewMatchesOptions options;
  options.scene = scene;
  options.num_matches = 400;
  options.noise_px = 0.5;
  options.outlier_ratio = 0.4;
  options.arc_deg = 20 + seed % 20;
  options.seed = seed;
  return testing::MakeTwoViewMatches(options);
}

RansacOptions TwoViewRansac(int seed) {
  RansacOptions options;
  options.max_error = 2.0;  // 4 sigma of the 0.5 px noise
  options.seed = seed;
  return options;
}

// Rotation of cam2_from_cam1 from E and the inliers (normalized points).
Rigid3d PoseFromE(const Eigen::Matrix3d& E, const testing::TwoViewMatches& m,
                  const std::vector<char>& mask) {
  std::vector<Eigen::Vector2d> x1, x2;
  for (std::size_t i = 0; i < mask.size(); ++i) {
    if (!mask[i]) continue;
    x1.push_back(m.camera.CamFromImg(m.points1[i]));
    x2.push_back(m.camera.CamFromImg(m.points2[i]));
  }
  Rigid3d pose;
  REQUIRE(RelativePoseFromEssential(E, x1, x2, &pose) > 0);
  return pose;
}

TEST_CASE("RANSAC + LO recovers F: rotation within 0.5 deg, > 95 % inliers right") {
  for (int seed = 0; seed < 20; ++seed) {
    const auto m = NoisyMatches(testing::TwoViewScene::kGeneral, seed);
    const auto result = EstimateFundamentalMatrix(m.points1, m.points2, TwoViewRansac(seed));
    REQUIRE(result.success);
    CHECK(testing::InlierClassificationRate(result.inlier_mask, m.is_inlier) > 0.95);
    const Eigen::Matrix3d K = CalibrationMatrix(m.camera);
    const Rigid3d pose = PoseFromE(EssentialFromFundamental(result.model, K, K), m,
                                   result.inlier_mask);
    CHECK(RotationDifferenceDeg(pose, m.Cam2FromCam1()) < 0.5);
  }
}

TEST_CASE("RANSAC + LO recovers E: rotation within 0.5 deg, > 95 % inliers right") {
  for (int seed = 0; seed < 20; ++seed) {
    const auto m = NoisyMatches(testing::TwoViewScene::kGeneral, 100 + seed);
    std::vector<Eigen::Vector2d> x1, x2;
    for (std::size_t i = 0; i < m.points1.size(); ++i) {
      x1.push_back(m.camera.CamFromImg(m.points1[i]));
      x2.push_back(m.camera.CamFromImg(m.points2[i]));
    }
    RansacOptions options = TwoViewRansac(seed);
    options.max_error = m.camera.CamFromImgThreshold(2.0);
    const auto result = EstimateEssentialMatrix(x1, x2, options);
    REQUIRE(result.success);
    CHECK(testing::InlierClassificationRate(result.inlier_mask, m.is_inlier) > 0.95);
    CHECK(RotationDifferenceDeg(PoseFromE(result.model, m, result.inlier_mask),
                                m.Cam2FromCam1()) < 0.5);
  }
}

TEST_CASE("RANSAC + LO recovers H: rotation within 0.5 deg, > 95 % inliers right") {
  for (int seed = 0; seed < 20; ++seed) {
    // Pure rotation: H = K R K^-1 gives the rotation directly.
    const auto m = NoisyMatches(testing::TwoViewScene::kPureRotation, 200 + seed);
    const auto result = EstimateHomographyMatrix(m.points1, m.points2, TwoViewRansac(seed));
    REQUIRE(result.success);
    CHECK(testing::InlierClassificationRate(result.inlier_mask, m.is_inlier) > 0.95);
    const Eigen::Matrix3d K = CalibrationMatrix(m.camera);
    const Eigen::Matrix3d M = K.inverse() * result.model * K;
    Eigen::JacobiSVD<Eigen::Matrix3d> svd(M, Eigen::ComputeFullU | Eigen::ComputeFullV);
    Eigen::Matrix3d R = svd.matrixU() * svd.matrixV().transpose();
    if (R.determinant() < 0) R = -R;
    CHECK(RotationDifferenceDeg(Rigid3d(R, Eigen::Vector3d::Zero()), m.Cam2FromCam1()) < 0.5);
  }
  for (int seed = 0; seed < 20; ++seed) {
    const auto m = NoisyMatches(testing::TwoViewScene::kPlanar, 300 + seed);
    const auto result = EstimateHomographyMatrix(m.points1, m.points2, TwoViewRansac(seed));
    REQUIRE(result.success);
    CHECK(testing::InlierClassificationRate(result.inlier_mask, m.is_inlier) > 0.95);
  }
}

}  // namespace
}  // namespace flysfm
