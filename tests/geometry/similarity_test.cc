#include "geometry/similarity.h"

#include <cmath>
#include <random>
#include <stdexcept>

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

// Noise of the correspondences, relative to the scale of the similarity: the
// source points fill the cube [-1, 1]^3, so it is 1 % of the cube's half-size
// once mapped into dst.
constexpr double kRelativeNoise = 0.01;

// The inlier threshold for isotropic Gaussian noise of standard deviation
// sigma per coordinate: |e|^2 / sigma^2 is chi-square with 3 degrees of
// freedom, of mean 3, so 3 sqrt(3) sigma (chi^2_3 > 27) cuts off a true
// inlier with probability 6e-6, and 2.4e-5 with the fitted model's own error
// (about sigma sqrt(7 / n), under 0.3 sigma here) taken off the margin.
double InlierThreshold(double sigma) { return 3 * std::sqrt(3.0) * sigma; }

Sim3d RandomSimilarity(std::mt19937& rng) {
  std::uniform_real_distribution<double> log_scale(-3, 3);
  const double scale = std::exp(log_scale(rng));
  return Sim3d(scale, testing::RandomRotation(rng),
               5 * scale * testing::RandomUnitVector(rng));
}

Eigen::Vector3d RandomInCube(std::mt19937& rng) {
  std::uniform_real_distribution<double> uniform(-1, 1);
  return {uniform(rng), uniform(rng), uniform(rng)};
}

Eigen::Vector3d Noise(std::mt19937& rng, double sigma) {
  std::normal_distribution<double> normal(0, sigma);
  return {normal(rng), normal(rng), normal(rng)};
}

// Bounds on the error of the least-squares similarity from n inliers in the
// cube under noise sigma = kRelativeNoise * scale, at 6 standard deviations
// per axis (a 3-vector of such errors exceeds 6 of them with probability
// 1e-7). The standard deviations follow from the information of the fit:
// scale sigma / (s sqrt(sum |x|^2)) relative, sum |x|^2 = n for the cube;
// rotation about an axis sigma / (s sqrt(n 2/3)), as the mean squared distance
// from an axis is 2/3; translation sigma / sqrt(n), from the mean of the noise
// (the rest, rotation error times the centroid of the points, ~1/sqrt(n)
// from the origin, adds a tenth of that: 7 instead of 6).
void CheckCloseTo(const Sim3d& estimate, const Sim3d& truth, int num_inliers) {
  const double n = num_inliers;
  const double sigma = kRelativeNoise * truth.scale;
  CHECK(std::abs(estimate.scale / truth.scale - 1) <
        6 * kRelativeNoise / std::sqrt(n));
  CHECK(estimate.rotation.angularDistance(truth.rotation) <
        6 * kRelativeNoise / std::sqrt(2 * n / 3));
  CHECK((estimate.translation - truth.translation).norm() < 7 * sigma / std::sqrt(n));
}

TEST_CASE("EstimateSimilarity finds a random similarity among 40 % outliers") {
  std::mt19937 rng(3);
  constexpr int kNumPairs = 200;
  for (int instance = 0; instance < 50; ++instance) {
    const Sim3d truth = RandomSimilarity(rng);
    const double sigma = kRelativeNoise * truth.scale;
    std::vector<Eigen::Vector3d> src, dst;
    std::vector<bool> is_inlier;
    for (int i = 0; i < kNumPairs; ++i) {
      src.push_back(RandomInCube(rng));
      // An outlier is a match to another, random point of the same scene.
      is_inlier.push_back(i % 5 >= 2);
      dst.push_back(is_inlier.back() ? Eigen::Vector3d(truth * src.back() + Noise(rng, sigma))
                                     : truth * RandomInCube(rng));
    }
    RansacOptions options;
    options.max_error = InlierThreshold(sigma);
    options.seed = instance;
    const RansacResult<Sim3d> result = EstimateSimilarity(src, dst, options);
    REQUIRE(result.success);
    const int num_true_inliers = kNumPairs * 3 / 5;
    CheckCloseTo(result.model, truth, num_true_inliers);
    int missed = 0, false_inliers = 0;
    for (int i = 0; i < kNumPairs; ++i) {
      missed += is_inlier[i] && !result.inlier_mask[i];
      false_inliers += !is_inlier[i] && result.inlier_mask[i];
    }
    // With a miss rate <= 2.4e-5 (see InlierThreshold), two misses among 120
    // inliers have probability 4e-6 per instance.
    CHECK(missed <= 1);
    // An outlier lands in the threshold ball (radius 0.052 in cube units)
    // around its predicted point with probability <= 4/3 pi 0.052^3 / 2^3 =
    // 7.4e-5: two among 80 with probability 1.7e-5.
    CHECK(false_inliers <= 1);
    CHECK(result.num_inliers == num_true_inliers - missed + false_inliers);
  }
}

TEST_CASE("EstimateSimilarity is not taken in by a smaller consistent wrong link") {
  // 60 correct matches under T; 25 matches from points of a facade to the
  // next repetition of the facade, all consistent with W = T * (shift by one
  // period); 40 random outliers.
  std::mt19937 rng(4);
  std::uniform_real_distribution<double> uniform(-1, 1);
  constexpr int kNumTrue = 60, kNumWrong = 25, kNumOutliers = 40;
  const Eigen::Vector3d period(0.8, 0, 0);
  for (int instance = 0; instance < 20; ++instance) {
    const Sim3d truth = RandomSimilarity(rng);
    const Sim3d wrong = truth * Sim3d(1, Eigen::Quaterniond::Identity(), period);
    const double sigma = kRelativeNoise * truth.scale;
    std::vector<Eigen::Vector3d> src, dst, wrong_src, wrong_dst;
    for (int i = 0; i < kNumTrue; ++i) {
      src.push_back(RandomInCube(rng));
      dst.push_back(truth * src.back() + Noise(rng, sigma));
    }
    for (int i = 0; i < kNumWrong; ++i) {
      wrong_src.emplace_back(uniform(rng), uniform(rng), 1);  // on the facade z = 1
      wrong_dst.push_back(wrong * wrong_src.back() + Noise(rng, sigma));
    }
    src.insert(src.end(), wrong_src.begin(), wrong_src.end());
    dst.insert(dst.end(), wrong_dst.begin(), wrong_dst.end());
    for (int i = 0; i < kNumOutliers; ++i) {
      src.push_back(RandomInCube(rng));
      dst.push_back(truth * RandomInCube(rng));
    }
    RansacOptions options;
    options.max_error = InlierThreshold(sigma);
    options.seed = instance;

    // The wrong link on its own is a valid similarity: the test is only
    // meaningful if it is a real competitor.
    const RansacResult<Sim3d> wrong_alone = EstimateSimilarity(wrong_src, wrong_dst, options);
    REQUIRE(wrong_alone.success);
    CHECK(wrong_alone.num_inliers >= kNumWrong - 1);

    const RansacResult<Sim3d> result = EstimateSimilarity(src, dst, options);
    REQUIRE(result.success);
    CheckCloseTo(result.model, truth, kNumTrue);
    int true_inliers = 0, wrong_inliers = 0;
    for (int i = 0; i < kNumTrue; ++i) true_inliers += result.inlier_mask[i];
    for (int i = kNumTrue; i < kNumTrue + kNumWrong; ++i) wrong_inliers += result.inlier_mask[i];
    // As in the test above, at most one true inlier beyond the threshold.
    CHECK(true_inliers >= kNumTrue - 1);
    // Under T the wrong matches are off by one period, s * 0.8 = 80 sigma,
    // far beyond the threshold of 5.2 sigma.
    CHECK(wrong_inliers == 0);
  }
}

TEST_CASE("EstimateSimilarity fails on degenerate or inconsistent input") {
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> uniform(-1, 1);
  const Sim3d truth = RandomSimilarity(rng);
  RansacOptions options;
  options.max_error = 0.01;

  // Collinear points fix no rotation about their line: every sample is
  // degenerate.
  const Eigen::Vector3d origin = RandomInCube(rng);
  const Eigen::Vector3d direction = testing::RandomUnitVector(rng);
  std::vector<Eigen::Vector3d> src, dst;
  for (int i = 0; i < 30; ++i) {
    src.push_back(origin + uniform(rng) * direction);
    dst.push_back(truth * src.back());
  }
  CHECK(!EstimateSimilarity(src, dst, options).success);

  const std::vector<Eigen::Vector3d> coincident(30, origin);
  CHECK(!EstimateSimilarity(coincident, coincident, options).success);

  std::vector<Eigen::Vector3d> src3, dst3;
  for (int i = 0; i < 3; ++i) {
    src3.push_back(RandomInCube(rng));
    dst3.push_back(truth * src3.back());
  }
  CHECK(EstimateSimilarity(src3, dst3, options).success);
  const std::vector<Eigen::Vector3d> src2(src3.begin(), src3.begin() + 2);
  const std::vector<Eigen::Vector3d> dst2(dst3.begin(), dst3.begin() + 2);
  CHECK(!EstimateSimilarity(src2, dst2, options).success);
  CHECK(!EstimateSimilarity({}, {}, options).success);
  CHECK(!EstimateSimilarity(src3, dst2, options).success);

  RansacOptions bad = options;
  bad.max_error = 0;
  CHECK_THROWS_AS(EstimateSimilarity(src3, dst3, bad), std::invalid_argument);
  CHECK_THROWS_AS(EstimateSimilarity(src3, dst2, bad), std::invalid_argument);
}

TEST_CASE("EstimateSimilarity gives equal results for equal seeds") {
  std::mt19937 rng(6);
  const Sim3d truth = RandomSimilarity(rng);
  const double sigma = kRelativeNoise * truth.scale;
  std::vector<Eigen::Vector3d> src, dst;
  for (int i = 0; i < 200; ++i) {
    src.push_back(RandomInCube(rng));
    dst.push_back(i % 2 ? Eigen::Vector3d(truth * src.back() + Noise(rng, sigma))
                        : truth * RandomInCube(rng));
  }
  RansacOptions options;
  options.max_error = InlierThreshold(sigma);
  options.seed = 7;
  const RansacResult<Sim3d> first = EstimateSimilarity(src, dst, options);
  const RansacResult<Sim3d> second = EstimateSimilarity(src, dst, options);
  REQUIRE(first.success);
  REQUIRE(second.success);
  CHECK(first.model.scale == second.model.scale);
  CHECK(first.model.rotation.coeffs() == second.model.rotation.coeffs());
  CHECK(first.model.translation == second.model.translation);
  CHECK(first.inlier_mask == second.inlier_mask);
  CHECK(first.num_iterations == second.num_iterations);
  CHECK(first.score == second.score);
}

}  // namespace
}  // namespace flysfm
