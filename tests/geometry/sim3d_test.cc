#include "geometry/sim3d.h"

#include <catch2/catch.hpp>

#include "tests/testing/synthetic.h"

namespace flysfm {
namespace {

TEST_CASE("Sim3d composes and inverts") {
  std::mt19937 rng(11);
  for (int i = 0; i < 100; ++i) {
    const Sim3d b_from_a(0.5 + i * 0.03, testing::RandomRotation(rng),
                         testing::RandomUnitVector(rng));
    const Sim3d c_from_b(2.0, testing::RandomRotation(rng),
                         testing::RandomUnitVector(rng) * 4);
    const Eigen::Vector3d x = testing::RandomUnitVector(rng);
    CHECK(((c_from_b * b_from_a) * x - c_from_b * (b_from_a * x)).norm() < 1e-12);
    CHECK((Inverse(b_from_a) * (b_from_a * x) - x).norm() < 1e-12);
  }
}

TEST_CASE("TransformPose keeps the projection of transformed points") {
  std::mt19937 rng(12);
  for (int i = 0; i < 50; ++i) {
    const Rigid3d cam_from_old(testing::RandomRotation(rng),
                               testing::RandomUnitVector(rng));
    const Sim3d new_from_old(1.7, testing::RandomRotation(rng),
                             testing::RandomUnitVector(rng) * 2);
    const Rigid3d cam_from_new = TransformPose(new_from_old, cam_from_old);
    const Eigen::Vector3d x_old = testing::RandomUnitVector(rng) * 3;
    const Eigen::Vector3d in_cam_old = cam_from_old * x_old;
    const Eigen::Vector3d in_cam_new = cam_from_new * (new_from_old * x_old);
    // Same ray, depth scaled by the similarity's scale.
    CHECK((in_cam_new - new_from_old.scale * in_cam_old).norm() < 1e-10);
  }
}

}  // namespace
}  // namespace flysfm
