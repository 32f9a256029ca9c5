#include "geometry/essential_matrix.h"

#include <cmath>

#include <catch2/catch.hpp>

#include "geometry/fundamental_matrix.h"
#include "tests/testing/synthetic.h"
#include "tests/testing/two_view_matches.h"

namespace flysfm {
namespace {

struct NormalizedMatches {
  std::vector<Eigen::Vector2d> x1, x2;
  Rigid3d cam2_from_cam1;
};

NormalizedMatches Instance(int seed, int num_matches, double noise_px = 0,
                           testing::TwoViewScene scene = testing::TwoViewScene::kGeneral) {
  testing::TwoViewMatchesOptions options;
  options.num_matches = num_matches;
  options.seed = seed;
  options.noise_px = noise_px;
  options.scene = scene;
  options.arc_deg = 5 + seed % 40;
  const auto matches = testing::MakeTwoViewMatches(options);
  NormalizedMatches result;
  for (std::size_t i = 0; i < matches.points1.size(); ++i) {
    result.x1.push_back(matches.camera.CamFromImg(matches.points1[i]));
    result.x2.push_back(matches.camera.CamFromImg(matches.points2[i]));
  }
  result.cam2_from_cam1 = matches.Cam2FromCam1();
  return result;
}

double BestDistance(const std::vector<Eigen::Matrix3d>& models,
                    const Eigen::Matrix3d& truth) {
  double best = std::numeric_limits<double>::infinity();
  for (const auto& model : models) best = std::min(best, ProjectiveMatrixDistance(model, truth));
  return best;
}

double TranslationAngleDeg(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return std::atan2(a.cross(b).norm(), a.dot(b)) * 180.0 / M_PI;
}

TEST_CASE("The 5-point algorithm recovers E exactly on 500 random scenes") {
  for (int seed = 0; seed < 500; ++seed) {
    const auto m = Instance(seed, 5);
    const auto models = EssentialFromFivePoints(m.x1, m.x2);
    REQUIRE(!models.empty());
    REQUIRE(models.size() <= 10);
    CHECK(BestDistance(models, EssentialFromPose(m.cam2_from_cam1)) < 1e-6);
    for (const auto& E : models) {
      // Every solution is an essential matrix: two equal singular values and
      // a zero one, and it satisfies the five constraints.
      const Eigen::Vector3d sigma = E.jacobiSvd().singularValues();
      CHECK(std::abs(sigma(0) - sigma(1)) < 1e-6 * sigma(0));
      CHECK(sigma(2) < 1e-6 * sigma(0));
      for (int i = 0; i < 5; ++i) {
        CHECK(std::abs(m.x2[i].homogeneous().dot(E * m.x1[i].homogeneous())) < 1e-9);
      }
    }
  }
}

TEST_CASE("The 5-point algorithm in least squares mode on n > 5 exact matches") {
  for (int seed = 0; seed < 100; ++seed) {
    const auto m = Instance(2000 + seed, 6 + seed % 40);
    const auto models = EssentialFromFivePoints(m.x1, m.x2);
    CHECK(BestDistance(models, EssentialFromPose(m.cam2_from_cam1)) < 1e-6);
  }
}

TEST_CASE("The 5-point algorithm handles planar scenes") {
  for (int seed = 0; seed < 100; ++seed) {
    const auto m = Instance(3000 + seed, 5, 0, testing::TwoViewScene::kPlanar);
    const auto models = EssentialFromFivePoints(m.x1, m.x2);
    CHECK(BestDistance(models, EssentialFromPose(m.cam2_from_cam1)) < 1e-6);
  }
}

TEST_CASE("The relative pose from E is found by cheirality on 500 random scenes") {
  for (int seed = 0; seed < 500; ++seed) {
    const auto m = Instance(4000 + seed, 50);
    Rigid3d pose;
    std::vector<Eigen::Vector3d> points;
    std::vector<char> in_front;
    const int count = RelativePoseFromEssential(EssentialFromPose(m.cam2_from_cam1),
                                                m.x1, m.x2, &pose, &points, &in_front);
    CHECK(count == 50);
    CHECK(RotationDifferenceDeg(pose, m.cam2_from_cam1) < 1e-6);
    CHECK(TranslationAngleDeg(pose.translation, m.cam2_from_cam1.translation) < 1e-6);
    CHECK(std::abs(pose.translation.norm() - 1) < 1e-12);
    REQUIRE(points.size() == 50);
    // Points are in camera-1 coordinates (unit baseline).
    for (int i = 0; i < 50; ++i) {
      CHECK(in_front[i]);
      const Eigen::Vector3d in_cam2 = pose * points[i];
      CHECK((in_cam2.hnormalized() - m.x2[i]).norm() < 1e-9);
      CHECK((points[i].hnormalized() - m.x1[i]).norm() < 1e-9);
      CHECK(points[i].z() > 0);
    }
  }
}

double SampsonCost(const NormalizedMatches& m, const Rigid3d& pose) {
  const Eigen::Matrix3d E = EssentialFromPose(pose);
  double cost = 0;
  for (std::size_t i = 0; i < m.x1.size(); ++i) {
    cost += FundamentalSampsonError(E, m.x1[i], m.x2[i]);
  }
  return cost;
}

TEST_CASE("RefineRelativePose converges to the least-squares optimum") {
  std::mt19937 rng(5);
  for (int seed = 0; seed < 50; ++seed) {
    for (const double noise_px : {0.0, 0.5}) {
      const auto m = Instance(5000 + 40 * seed + 25, 100, noise_px);
      Rigid3d truth = m.cam2_from_cam1;
      truth.translation.normalize();
      Rigid3d pose(testing::RandomRotationOfAngle(rng, 2.0) * truth.rotation,
                   (truth.translation + 0.1 * testing::RandomUnitVector(rng)).normalized());
      REQUIRE(RefineRelativePose(m.x1, m.x2, {}, &pose));
      if (noise_px == 0) {
        CHECK(RotationDifferenceDeg(pose, truth) < 1e-6);
        CHECK(TranslationAngleDeg(pose.translation, truth.translation) < 1e-6);
      } else {
        // The optimum fits the noisy data at least as well as the truth.
        CHECK(SampsonCost(m, pose) <= SampsonCost(m, truth) * (1 + 1e-9));
      }
    }
  }
}

TEST_CASE("Essential solvers return nothing for degenerate input") {
  const auto m = Instance(9, 5);
  CHECK(EssentialFromFivePoints({m.x1.begin(), m.x1.begin() + 4},
                                {m.x2.begin(), m.x2.begin() + 4}).empty());
  CHECK(EssentialFromFivePoints(m.x1, {m.x2.begin(), m.x2.begin() + 4}).empty());
  auto bad = m.x1;
  bad[0].x() = std::numeric_limits<double>::quiet_NaN();
  CHECK(EssentialFromFivePoints(bad, m.x2).empty());
  CHECK(EssentialFromFivePoints(std::vector<Eigen::Vector2d>(5, m.x1[0]),
                                std::vector<Eigen::Vector2d>(5, m.x2[0])).empty());
  // Two repeated matches leave four distinct ones: not enough.
  CHECK(EssentialFromFivePoints({m.x1[0], m.x1[1], m.x1[2], m.x1[0], m.x1[1]},
                                {m.x2[0], m.x2[1], m.x2[2], m.x2[0], m.x2[1]}).empty());
  Rigid3d pose;
  CHECK(RelativePoseFromEssential(Eigen::Matrix3d::Zero(), m.x1, m.x2, &pose) == 0);
  Eigen::Matrix3d nan_E = Eigen::Matrix3d::Identity();
  nan_E(0, 0) = std::numeric_limits<double>::quiet_NaN();
  CHECK(RelativePoseFromEssential(nan_E, m.x1, m.x2, &pose) == 0);
}

}  // namespace
}  // namespace flysfm
