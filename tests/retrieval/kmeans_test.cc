#include "retrieval/kmeans.h"

#include <random>
#include <set>

#include <catch2/catch.hpp>

namespace flysfm {
namespace {

TEST_CASE("k-means recovers well separated clusters") {
  // Four blobs of radius ~0.05 around centres 10 apart.
  std::mt19937 rng(3);
  std::normal_distribution<float> noise(0.f, 0.05f);
  RowMatrixXf truth(4, 8);
  truth.setZero();
  for (int c = 0; c < 4; ++c) truth(c, c) = 10.f;
  RowMatrixXf points(400, 8);
  for (int i = 0; i < 400; ++i) {
    for (int d = 0; d < 8; ++d) points(i, d) = truth(i % 4, d) + noise(rng);
  }
  std::vector<int> assignment;
  const RowMatrixXf centres = KMeans(points, 4, KMeansOptions(), &assignment);
  REQUIRE(centres.rows() == 4);
  // Each true centre has a found centre within the noise level.
  for (int c = 0; c < 4; ++c) {
    float best = 1e9f;
    for (int k = 0; k < 4; ++k) best = std::min(best, (centres.row(k) - truth.row(c)).norm());
    CHECK(best < 0.05f);
  }
  // Points of one blob share one label, different blobs different labels.
  std::set<int> labels;
  for (int c = 0; c < 4; ++c) {
    for (int i = c; i < 400; i += 4) REQUIRE(assignment[i] == assignment[c]);
    labels.insert(assignment[c]);
  }
  CHECK(labels.size() == 4);
  CHECK(AssignToNearest(truth, centres) ==
        std::vector<int>{assignment[0], assignment[1], assignment[2], assignment[3]});
}

TEST_CASE("k-means with fewer points than clusters returns the points") {
  RowMatrixXf points(2, 3);
  points << 1, 2, 3, 4, 5, 6;
  const RowMatrixXf centres = KMeans(points, 5, KMeansOptions());
  CHECK(IdenticalMatrices(centres, points));
  // Identical points collapse to one centre.
  const RowMatrixXf same = RowMatrixXf::Ones(10, 3);
  CHECK(KMeans(same, 3, KMeansOptions()).rows() == 1);
}

}  // namespace
}  // namespace flysfm
