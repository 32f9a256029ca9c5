#include "geometry/rigid3d.h"

#include <catch2/catch.hpp>

#include "tests/testing/synthetic.h"

namespace flysfm {
namespace {

TEST_CASE("Rigid3d composes, inverts and applies consistently") {
  std::mt19937 rng(7);
  for (int i = 0; i < 100; ++i) {
    const Rigid3d b_from_a(testing::RandomRotation(rng),
                           testing::RandomUnitVector(rng) * 3);
    const Rigid3d c_from_b(testing::RandomRotation(rng),
                           testing::RandomUnitVector(rng));
    const Eigen::Vector3d x = testing::RandomUnitVector(rng) * 2;
    CHECK(((c_from_b * b_from_a) * x - c_from_b * (b_from_a * x)).norm() < 1e-12);
    CHECK((Inverse(b_from_a) * (b_from_a * x) - x).norm() < 1e-12);
    CHECK((b_from_a.ToMatrix() * x.homogeneous() - b_from_a * x).norm() < 1e-12);
    CHECK(RotationDifferenceDeg(b_from_a, b_from_a) < 1e-6);
  }
}

TEST_CASE("The projection centre maps to the camera origin") {
  std::mt19937 rng(8);
  const Rigid3d cam_from_world(testing::RandomRotation(rng), Eigen::Vector3d(1, 2, 3));
  CHECK((cam_from_world * ProjectionCenter(cam_from_world)).norm() < 1e-12);
}

TEST_CASE("RotationDifferenceDeg measures the relative angle") {
  std::mt19937 rng(9);
  const Rigid3d a(testing::RandomRotation(rng), Eigen::Vector3d::Zero());
  const Rigid3d b(testing::RandomRotationOfAngle(rng, 12.5) * a.rotation,
                  Eigen::Vector3d::Zero());
  CHECK(RotationDifferenceDeg(a, b) == Approx(12.5).margin(1e-9));
}

}  // namespace
}  // namespace flysfm
