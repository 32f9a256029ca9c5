#include "matching/matcher.h"

#include <algorithm>
#include <numeric>
#include <random>
#include <set>
#include <stdexcept>

#include <catch2/catch.hpp>

#include "io/synthetic/procedural_texture.h"
#include "tests/testing/warped_pair.h"

namespace flysfm {
namespace {

MatchOptions Options(MatcherBackend backend) {
  MatchOptions options;
  options.backend = backend;
  return options;
}

// RootSIFT of a texture's features, what the matcher compares.
const FeatureDescriptors& TextureDescriptors() {
  static const FeatureDescriptors descriptors =
      RootSift(ExtractFeatures(MakeTexture(640, 480, 11), SiftOptions()).descriptors);
  return descriptors;
}

TEST_CASE("ratio and mutual tests reject a shuffled-descriptor pair") {
  const FeatureDescriptors& d1 = TextureDescriptors();
  REQUIRE(d1.rows() > 500);
  // Each descriptor's 128 bins permuted at random: same statistics as real
  // RootSIFT, no true correspondence.
  std::mt19937 rng(4);
  FeatureDescriptors d2 = d1;
  std::vector<int> order(128);
  std::iota(order.begin(), order.end(), 0);
  for (Eigen::Index i = 0; i < d2.rows(); ++i) {
    std::shuffle(order.begin(), order.end(), rng);
    for (int k = 0; k < 128; ++k) d2(i, k) = d1(i, order[k]);
  }
  for (const MatcherBackend backend : {MatcherBackend::kExact, MatcherBackend::kApproximate}) {
    MatchOptions none = Options(backend);
    none.max_ratio = 1.0;
    none.mutual = false;
    // Without the tests, nearly every descriptor finds a "match".
    CHECK(MatchDescriptors(d1, d2, none).size() >= std::size_t(0.95 * d1.rows()));
    // With them, at most 1 % survive.
    CHECK(MatchDescriptors(d1, d2, Options(backend)).size() <= std::size_t(0.01 * d1.rows()));
  }
}

TEST_CASE("a permuted copy matches one-to-one with both back-ends") {
  const FeatureDescriptors& d1 = TextureDescriptors();
  std::vector<int> permutation(d1.rows());
  std::iota(permutation.begin(), permutation.end(), 0);
  std::mt19937 rng(5);
  std::shuffle(permutation.begin(), permutation.end(), rng);
  FeatureDescriptors d2(d1.rows(), 128);
  for (Eigen::Index i = 0; i < d1.rows(); ++i) d2.row(permutation[i]) = d1.row(i);
  for (const MatcherBackend backend : {MatcherBackend::kExact, MatcherBackend::kApproximate}) {
    const std::vector<FeatureMatch> matches = MatchDescriptors(d1, d2, Options(backend));
    // Keypoints at one position with several orientations have nearly equal
    // descriptors and fail the ratio test; the rest must all be found.
    CHECK(matches.size() >= std::size_t(0.9 * d1.rows()));
    for (const FeatureMatch& m : matches) REQUIRE(m.idx2 == permutation[m.idx1]);
  }
}

TEST_CASE("approximate matching finds most exact matches on a warped pair") {
  const testing::WarpedPair pair = testing::MakeWarpedPair(640, 480, 20.0, 1.1, 640, 480, 9);
  const FeatureSet f1 = ExtractFeatures(pair.image1, SiftOptions());
  const FeatureSet f2 = ExtractFeatures(pair.image2, SiftOptions());
  const FeatureDescriptors d1 = RootSift(f1.descriptors), d2 = RootSift(f2.descriptors);
  const auto exact = MatchDescriptors(d1, d2, Options(MatcherBackend::kExact));
  const auto approx = MatchDescriptors(d1, d2, Options(MatcherBackend::kApproximate));
  REQUIRE(exact.size() >= 200);
  std::set<std::pair<int, int>> exact_set;
  for (const FeatureMatch& m : exact) exact_set.insert({m.idx1, m.idx2});
  int common = 0;
  for (const FeatureMatch& m : approx) common += exact_set.count({m.idx1, m.idx2});
  CHECK(common >= 0.9 * exact.size());
  // Matches are unique on both sides (mutual check).
  std::set<int> seen2;
  for (const FeatureMatch& m : exact) REQUIRE(seen2.insert(m.idx2).second);
}

TEST_CASE("empty inputs give no matches and bad options are rejected") {
  const FeatureDescriptors& d = TextureDescriptors();
  const FeatureDescriptors empty(0, 128);
  CHECK(MatchDescriptors(empty, d, {}).empty());
  CHECK(MatchDescriptors(d, empty, Options(MatcherBackend::kApproximate)).empty());
  // One candidate only: no second neighbour, so the ratio test cannot pass.
  CHECK(MatchDescriptors(d.topRows(5), d.topRows(1), {}).empty());
  MatchOptions bad;
  bad.max_ratio = 1.5;
  CHECK_FALSE(bad.Check());
  CHECK_THROWS_AS(MatchDescriptors(d, d, bad), std::invalid_argument);
}

}  // namespace
}  // namespace flysfm
