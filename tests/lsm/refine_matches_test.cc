#include "lsm/refine_matches.h"

#include <random>
#include <vector>

#include <Eigen/Geometry>
#include <catch2/catch.hpp>

#include "tests/testing/affine_pair.h"

namespace flysfm {
namespace {

TEST_CASE("A feature is matched on the pyramid level of its scale") {
  const int window = LsmOptions().window_size;
  CHECK(FeatureLevel(0.0, window, 3) == 0);
  CHECK(FeatureLevel(11.9, window, 3) == 0);
  CHECK(FeatureLevel(12.0, window, 3) == 1);
  CHECK(FeatureLevel(23.9, window, 3) == 1);
  CHECK(FeatureLevel(24.0, window, 3) == 2);
  CHECK(FeatureLevel(1000.0, window, 3) == 2);
  CHECK(FeatureLevel(1000.0, window, 1) == 0);
}

struct Outcome {
  int true_kept = 0;
  int false_kept = 0;
  int within_tolerance = 0;
};

// 200 true matches with SIFT-like noise (half a pixel of image 1, mapped)
// and 100 unrelated positions; the features' frames say `scale1` and
// `scale2`, and a turn of `turn` from image 1 to image 2.
Outcome RefineRandomMatches(const testing::AffinePair& pair, double scale1, double scale2,
                            double turn, double tolerance_px) {
  const std::vector<LsmImage> pyramid1 = BuildLsmPyramid(pair.image1, 3);
  const std::vector<LsmImage> pyramid2 = BuildLsmPyramid(pair.image2, 3);
  std::mt19937 rng(8);
  // Where image 2 shows image 1 even magnified 2x about the centre, with a
  // turned window's reach from its border on the coarsest level.
  std::uniform_real_distribution<double> x(0.35 * pair.image1.cols, 0.65 * pair.image1.cols);
  std::uniform_real_distribution<double> y(0.35 * pair.image1.rows, 0.65 * pair.image1.rows);
  std::normal_distribution<double> noise(0.0, 0.5);
  constexpr int kNumTrue = 200;
  constexpr int kNumFalse = 100;
  LsmMatcher matcher{LsmOptions()};
  Outcome outcome;
  for (int i = 0; i < kNumTrue + kNumFalse; ++i) {
    const FeatureFrame feature1{Eigen::Vector2d(x(rng), y(rng)), scale1, 0.3};
    FeatureFrame feature2{Eigen::Vector2d(x(rng), y(rng)), scale2, 0.3 + turn};
    if (i < kNumTrue) {
      feature2.xy = pair.Map(feature1.xy) + pair.linear * Eigen::Vector2d(noise(rng), noise(rng));
    }
    const RefinedMatch refined = RefineMatch(
        [&](int level) { return pyramid1[level]; }, feature1, pyramid2, feature2, &matcher);
    if (!refined.Converged()) continue;
    if (i >= kNumTrue) {
      ++outcome.false_kept;
      continue;
    }
    ++outcome.true_kept;
    outcome.within_tolerance += (refined.point2 - pair.Map(feature1.xy)).norm() < tolerance_px;
  }
  return outcome;
}

TEST_CASE("RefineMatch refines true matches and drops false ones") {
  testing::AffinePairOptions options;
  options.width = 480;
  options.height = 360;
  options.linear = 1.1 * Eigen::Rotation2Dd(10.0 * M_PI / 180.0).toRotationMatrix();
  options.translation = Eigen::Vector2d(4.2, -2.6);
  options.brightness = 10.0;
  options.contrast = 0.9;
  const testing::AffinePair pair = testing::MakeAffinePair(options);
  // Features of the window's size: level 0 only. Frames that do not say the
  // scale or the turn (0 and 0) start from the identity, which reaches 1.1x
  // and 10 deg.
  Outcome outcome = RefineRandomMatches(pair, 5.0, 5.5, 10.0 * M_PI / 180.0, 0.02);
  CHECK(outcome.true_kept >= 0.95 * 200);
  CHECK(outcome.within_tolerance >= 0.99 * outcome.true_kept);
  CHECK(outcome.false_kept <= 1);
  outcome = RefineRandomMatches(pair, 0.0, 0.0, 0.0, 0.02);
  CHECK(outcome.true_kept >= 0.95 * 200);
  CHECK(outcome.false_kept <= 1);
  // A scale on one side only says nothing of the magnification either.
  outcome = RefineRandomMatches(pair, 5.0, 0.0, 0.0, 0.02);
  CHECK(outcome.true_kept >= 0.95 * 200);
  CHECK(outcome.false_kept <= 1);
}

// A view from twice as near, turned by 35 deg: the features are matched on
// their levels (1 and 2) from the SIFT frames' similarity, then sharpened on
// full resolution.
TEST_CASE("Large features are matched on their levels across a 2x magnification") {
  testing::AffinePairOptions options;
  options.width = 640;
  options.height = 480;
  options.linear = 2.0 * Eigen::Rotation2Dd(35.0 * M_PI / 180.0).toRotationMatrix();
  options.blur_sigma = 1.5;
  const testing::AffinePair pair = testing::MakeAffinePair(options);
  const Outcome outcome = RefineRandomMatches(pair, 16.0, 32.0, 35.0 * M_PI / 180.0, 0.05);
  CHECK(outcome.true_kept >= 0.9 * 200);
  CHECK(outcome.within_tolerance >= 0.95 * outcome.true_kept);
  CHECK(outcome.false_kept <= 1);
}

TEST_CASE("RefineMatch without a pyramid to search converges nowhere") {
  const std::vector<LsmImage> pyramid = BuildLsmPyramid(cv::Mat(100, 100, CV_8U, cv::Scalar(0)), 1);
  LsmMatcher matcher{LsmOptions()};
  const FeatureFrame frame{Eigen::Vector2d(50, 50), 5.0, 0.0};
  CHECK_FALSE(
      RefineMatch([&](int level) { return pyramid[level]; }, frame, {}, frame, &matcher)
          .Converged());
}

}  // namespace
}  // namespace flysfm
