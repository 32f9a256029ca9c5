#include "geometry/similarity.h"

#include <catch2/catch.hpp>

#include "tests/testing/synthetic.h"

namespace flysfm {
namespace {

TEST_CASE("SimilarityFromPoints recovers a random similarity exactly") {
  std::mt19937 rng(1);
  std::uniform_real_distribution<double> uniform(-1, 1);
  std::uniform_real_distribution<double> log_scale(-3, 3);
  for (int instance = 0; instance < 500; ++instance) {
    const Sim3d truth(std::exp(log_scale(rng)), testing::RandomRotation(rng),
                      10 * testing::RandomUnitVector(rng));
    std::vector<Eigen::Vector3d> src, dst;
    for (int i = 0; i < 3 + instance % 30; ++i) {
      src.emplace_back(uniform(rng), uniform(rng), uniform(rng));
      dst.push_back(truth * src.back());
    }
    const auto estimate = SimilarityFromPoints(src, dst);
    REQUIRE(estimate);
    CHECK(std::abs(estimate->scale / truth.scale - 1) < 1e-9);
    CHECK(estimate->rotation.angularDistance(truth.rotation) < 1e-9);
    CHECK((estimate->translation - truth.translation).norm() < 1e-9 * truth.translation.norm());
    const auto rigid = RigidFromPoints(src, dst);
    REQUIRE(rigid);
    if (std::abs(truth.scale - 1) > 0.1) {
      // Without scale the fit cannot be exact.
      double residual = 0;
      for (std::size_t i = 0; i < src.size(); ++i) residual += ((*rigid) * src[i] - dst[i]).norm();
      CHECK(residual > 1e-6);
    }
  }
}

TEST_CASE("RigidFromPoints recovers a random rigid transform exactly") {
  std::mt19937 rng(2);
  std::uniform_real_distribution<double> uniform(-2, 2);
  for (int instance = 0; instance < 500; ++instance) {
    const Rigid3d truth(testing::RandomRotation(rng), testing::RandomUnitVector(rng));
    std::vector<Eigen::Vector3d> src, dst;
    for (int i = 0; i < 3 + instance % 10; ++i) {
      src.emplace_back(uniform(rng), uniform(rng), uniform(rng));
      dst.push_back(truth * src.back());
    }
    const auto estimate = RigidFromPoints(src, dst);
    REQUIRE(estimate);
    CHECK(RotationDifferenceDeg(*estimate, truth) < 1e-7);
    CHECK((estimate->translation - truth.translation).norm() < 1e-9);
  }
}

TEST_CASE("Alignment returns nothing for degenerate input") {
  const std::vector<Eigen::Vector3d> a = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
  CHECK(!SimilarityFromPoints({a[0], a[1]}, {a[0], a[1]}));
  CHECK(!SimilarityFromPoints(a, {a[0], a[1], a[2]}));
  CHECK(!SimilarityFromPoints({a[0], a[1], {2, 0, 0}}, {a[0], a[1], a[2]}));  // collinear
  CHECK(!SimilarityFromPoints(std::vector<Eigen::Vector3d>(4, a[1]), a));
  auto bad = a;
  bad[2].x() = std::numeric_limits<double>::quiet_NaN();
  CHECK(!SimilarityFromPoints(a, bad));
  CHECK(!RigidFromPoints(bad, a));
}

}  // namespace
}  // namespace flysfm
