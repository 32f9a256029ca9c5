#include "retrieval/vlad.h"

#include <sstream>
#include <stdexcept>

#include <catch2/catch.hpp>

#include "tests/retrieval/place_features.h"
#include "tests/testing/warped_pair.h"

namespace flysfm {
namespace {

TEST_CASE("VLAD of real SIFT ranks a warped view of the same texture first") {
  // Six textures, each seen twice: as is and rotated/scaled. The second
  // view's nearest first view must be its own texture's.
  std::vector<FeatureSet> first, second;
  for (int t = 0; t < 6; ++t) {
    const testing::WarpedPair pair =
        testing::MakeWarpedPair(320, 240, 10.0 + 5 * t, 0.9, 320, 240, 100 + t);
    first.push_back(ExtractFeatures(pair.image1, SiftOptions()));
    second.push_back(ExtractFeatures(pair.image2, SiftOptions()));
  }
  std::vector<const FeatureSet*> training;
  for (const FeatureSet& f : first) training.push_back(&f);
  VladOptions options;
  options.num_words = 16;
  options.min_pca_samples = 20;
  options.crops_per_image = 8;
  const VladExtractor vlad = VladExtractor::Train(training, options);
  REQUIRE(vlad.HasPca());
  // 6 images x (1 + 8 crops) samples: at most 53 dimensions.
  CHECK(vlad.Dim() <= 53);
  for (int t = 0; t < 6; ++t) {
    const Eigen::VectorXf query = vlad.Compute(second[t]);
    REQUIRE(query.norm() == Approx(1.0).margin(1e-4));
    int best = -1;
    float best_distance = 1e9f;
    for (int k = 0; k < 6; ++k) {
      const float d = (vlad.Compute(first[k]) - query).norm();
      if (d < best_distance) {
        best_distance = d;
        best = k;
      }
    }
    CHECK(best == t);
  }
}

TEST_CASE("raw VLAD has one unit block per word before PCA") {
  testing::PlaceFeatures places(3, 1);
  std::vector<FeatureSet> views;
  for (int p = 0; p < 3; ++p) views.push_back(places.View(p));
  std::vector<const FeatureSet*> training;
  for (const FeatureSet& f : views) training.push_back(&f);
  VladOptions options;
  options.num_words = 8;
  options.power = 1.0;  // intra-normalised blocks stay unit vectors
  const VladExtractor vlad = VladExtractor::Train(training, options);
  CHECK_FALSE(vlad.HasPca());  // 3 x 9 samples < min_pca_samples
  CHECK(vlad.Dim() == 8 * 128);
  const Eigen::VectorXf raw = vlad.ComputeRaw(views[0]);
  REQUIRE(raw.size() == 8 * 128);
  int non_empty = 0;
  for (int w = 0; w < 8; ++w) non_empty += raw.segment(w * 128, 128).norm() > 0;
  CHECK(non_empty >= 2);
  CHECK(raw.norm() == Approx(1.0).margin(1e-5));
  // Each non-empty block has the same norm: 1 / sqrt(non-empty blocks).
  for (int w = 0; w < 8; ++w) {
    const float block = raw.segment(w * 128, 128).norm();
    if (block > 0) CHECK(block == Approx(1.0 / std::sqrt(non_empty)).margin(1e-5));
  }
  // No features: a zero raw vector, not a NaN.
  const FeatureSet empty;
  CHECK(vlad.ComputeRaw(empty).isZero());
}

TEST_CASE("VLAD write and read round-trip exactly and reject corrupt data") {
  testing::PlaceFeatures places(40, 2);
  std::vector<FeatureSet> views;
  for (int p = 0; p < 40; ++p) views.push_back(places.View(p));
  std::vector<const FeatureSet*> training;
  for (const FeatureSet& f : views) training.push_back(&f);
  VladOptions options;
  options.num_words = 8;
  options.pca_dim = 32;
  const VladExtractor vlad = VladExtractor::Train(training, options);
  REQUIRE(vlad.HasPca());
  CHECK(vlad.Dim() == 32);
  std::stringstream stream;
  vlad.Write(stream);
  const std::string bytes = stream.str();
  std::istringstream in(bytes);
  const VladExtractor read = VladExtractor::Read(in);
  CHECK(read == vlad);
  CHECK(read.Compute(views[3]) == vlad.Compute(views[3]));
  std::istringstream cut(bytes.substr(0, bytes.size() - 10));
  CHECK_THROWS_AS(VladExtractor::Read(cut), std::runtime_error);

  CHECK_THROWS_AS(VladExtractor::Train({}, options), std::invalid_argument);
  VladOptions bad;
  bad.num_words = 0;
  CHECK_THROWS_AS(VladExtractor::Train(training, bad), std::invalid_argument);
}

}  // namespace
}  // namespace flysfm
