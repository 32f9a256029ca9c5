// Garbage in, nothing out, never a crash: every solver and robust estimator
// of geometry/ on random mixtures of NaN, infinities, huge values,
// duplicates and collinear points.

#include <cmath>
#include <limits>
#include <random>

#include <catch2/catch.hpp>

#include "geometry/absolute_pose.h"
#include "geometry/essential_matrix.h"
#include "geometry/fundamental_matrix.h"
#include "geometry/homography_matrix.h"
#include "geometry/similarity.h"
#include "geometry/triangulation.h"
#include "geometry/two_view_geometry.h"

namespace flysfm {
namespace {

// A value that is NaN, +-inf, 0, huge, or repeats the previous one.
double Garbage(std::mt19937& rng, double previous) {
  std::uniform_int_distribution<int> kind(0, 6);
  std::uniform_real_distribution<double> uniform(-500, 500);
  switch (kind(rng)) {
    case 0: return std::numeric_limits<double>::quiet_NaN();
    case 1: return std::numeric_limits<double>::infinity();
    case 2: return -std::numeric_limits<double>::infinity();
    case 3: return 0.0;
    case 4: return 1e300;
    case 5: return previous;
    default: return uniform(rng);
  }
}

std::vector<Eigen::Vector2d> Points2D(std::mt19937& rng, int n) {
  std::vector<Eigen::Vector2d> points;
  double last = 1;
  for (int i = 0; i < n; ++i) {
    const double x = Garbage(rng, last);
    const double y = Garbage(rng, x);
    points.emplace_back(x, y);
    last = y;
  }
  return points;
}

std::vector<Eigen::Vector3d> Points3D(std::mt19937& rng, int n) {
  std::vector<Eigen::Vector3d> points;
  double last = 1;
  for (int i = 0; i < n; ++i) {
    const double x = Garbage(rng, last), y = Garbage(rng, x), z = Garbage(rng, y);
    points.emplace_back(x, y, z);
    last = z;
  }
  return points;
}

bool AllFinite(const std::vector<Eigen::Matrix3d>& models) {
  for (const auto& m : models) {
    if (!m.allFinite()) return false;
  }
  return true;
}

TEST_CASE("Solvers never crash on garbage and return only finite models") {
  std::mt19937 rng(1);
  for (int trial = 0; trial < 300; ++trial) {
    const int n = trial % 12;
    const auto a = Points2D(rng, n), b = Points2D(rng, n);
    const auto X = Points3D(rng, n);
    CHECK(AllFinite(FundamentalFromSevenPoints(a, b)));
    CHECK(AllFinite(FundamentalFromEightPoints(a, b)));
    CHECK(AllFinite(HomographyFromPoints(a, b)));
    CHECK(AllFinite(EssentialFromFivePoints(a, b)));
    for (const auto& pose : P3P(a, X)) CHECK(pose.translation.allFinite());
    for (const auto& pose : EPnP(a, X)) CHECK(pose.translation.allFinite());
    if (const auto sim = SimilarityFromPoints(X, X)) CHECK(sim->translation.allFinite());
    if (n >= 2) {
      const auto point = TriangulatePoint(Matrix3x4d::Identity(), Matrix3x4d::Random(), a[0], a[1]);
      if (point) CHECK(point->allFinite());
    }
  }
}

TEST_CASE("Robust estimators never crash on garbage") {
  std::mt19937 rng(2);
  const Camera camera = Camera::FromFocal(CameraModelId::kSimpleRadial, 300, 640, 480);
  for (int trial = 0; trial < 30; ++trial) {
    const int n = 5 * trial;
    const auto a = Points2D(rng, n), b = Points2D(rng, n);
    const auto X = Points3D(rng, n);
    RansacOptions ransac;
    ransac.max_iterations = 200;
    CHECK_NOTHROW(EstimateFundamentalMatrix(a, b, ransac));
    CHECK_NOTHROW(EstimateHomographyMatrix(a, b, ransac));
    CHECK_NOTHROW(EstimateEssentialMatrix(a, b, ransac));
    TwoViewGeometryOptions two_view;
    two_view.ransac.max_iterations = 200;
    const auto g = EstimateCalibratedTwoViewGeometry(camera, a, camera, b, two_view);
    CHECK(g.inlier_mask.size() == a.size());
    AbsolutePoseOptions absolute;
    absolute.ransac.max_iterations = 200;
    const auto pose = EstimateAbsolutePose(camera, a, X, absolute);
    if (pose.success) CHECK(pose.cam_from_world.translation.allFinite());
    std::vector<TriangulationObservation> observations;
    for (int i = 0; i < n; ++i) {
      observations.push_back({Rigid3d(Eigen::Quaterniond::Identity(), X[i]), &camera, a[i]});
    }
    const auto point = EstimateTriangulation(observations, TriangulationOptions());
    if (point.success) CHECK(point.point.allFinite());
  }
}

}  // namespace
}  // namespace flysfm
