#include "lsm/refine_matches.h"

#include <random>
#include <vector>

#include <Eigen/Geometry>
#include <catch2/catch.hpp>

#include "tests/testing/affine_pair.h"

namespace flysfm {
namespace {

TEST_CASE("RefineMatches refines true matches and drops false ones") {
  testing::AffinePairOptions pair_options;
  pair_options.width = 480;
  pair_options.height = 360;
  pair_options.linear =
      1.1 * Eigen::Rotation2Dd(10.0 * M_PI / 180.0).toRotationMatrix();
  pair_options.translation = Eigen::Vector2d(4.2, -2.6);
  pair_options.brightness = 10.0;
  pair_options.contrast = 0.9;
  const testing::AffinePair pair = testing::MakeAffinePair(pair_options);

  std::mt19937 rng(8);
  std::uniform_real_distribution<double> x(60.0, 420.0);
  std::uniform_real_distribution<double> y(60.0, 300.0);
  // SIFT-like noise on the true matches.
  std::normal_distribution<double> noise(0.0, 0.5);
  constexpr int kNumTrue = 200;
  constexpr int kNumFalse = 100;
  std::vector<Eigen::Vector2d> points1;
  std::vector<Eigen::Vector2d> points2;
  for (int i = 0; i < kNumTrue + kNumFalse; ++i) {
    points1.emplace_back(x(rng), y(rng));
    if (i < kNumTrue) {
      points2.push_back(pair.Map(points1.back()) +
                        Eigen::Vector2d(noise(rng), noise(rng)));
    } else {
      points2.emplace_back(x(rng), y(rng));  // unrelated position
    }
  }

  const RefineMatchesResult refined =
      RefineMatches(pair.image1, pair.image2, points1, points2);
  REQUIRE(refined.results.size() == points1.size());
  CHECK(refined.counts.Total() == static_cast<int>(points1.size()));
  CHECK(refined.counts[LsmStatus::kConverged] ==
        static_cast<int>(refined.inliers.size()));

  int true_kept = 0;
  int false_kept = 0;
  int within_tolerance = 0;
  for (const int i : refined.inliers) {
    REQUIRE(refined.results[i].Converged());
    if (i >= kNumTrue) {
      ++false_kept;
      continue;
    }
    ++true_kept;
    within_tolerance +=
        (refined.results[i].point2 - pair.Map(points1[i])).norm() < 0.02;
  }
  CHECK(true_kept >= 0.95 * kNumTrue);
  CHECK(within_tolerance >= 0.99 * true_kept);
  CHECK(false_kept <= 1);

  // Failures are counted under their reasons.
  int failures = 0;
  for (int s = 1; s < kNumLsmStatus; ++s) {
    failures += refined.counts[static_cast<LsmStatus>(s)];
  }
  CHECK(failures == static_cast<int>(points1.size() - refined.inliers.size()));

  // The prepared-image overload gives the same answer.
  const RefineMatchesResult again = RefineMatches(
      LsmImage(pair.image1), LsmImage(pair.image2), points1, points2);
  CHECK(again.inliers == refined.inliers);
}

TEST_CASE("RefineMatches rejects lists of different sizes") {
  const cv::Mat image(100, 100, CV_8U, cv::Scalar(0));
  CHECK_THROWS_AS(RefineMatches(image, image, {Eigen::Vector2d(50, 50)}, {}),
                  std::invalid_argument);
  const RefineMatchesResult empty = RefineMatches(image, image, {}, {});
  CHECK(empty.results.empty());
  CHECK(empty.inliers.empty());
}

}  // namespace
}  // namespace flysfm
