#include "retrieval/image_index.h"

#include <algorithm>
#include <memory>
#include <random>
#include <set>
#include <stdexcept>

#include <catch2/catch.hpp>

namespace flysfm {
namespace {

constexpr int kDim = 256;

Eigen::VectorXf RandomUnit(std::mt19937& rng) {
  std::normal_distribution<float> normal(0.f, 1.f);
  Eigen::VectorXf v(kDim);
  for (int d = 0; d < kDim; ++d) v[d] = normal(rng);
  return v.normalized();
}

TEST_CASE("tree queries return the exhaustive top-1 for >= 95 % of queries") {
  // 3 000 random unit descriptors inserted; each query is an inserted one
  // moved by noise of norm 0.7 (random unit vectors are ~1.41 apart), so its
  // exhaustive nearest neighbour is unambiguous but not trivially the query.
  std::mt19937 rng(7);
  const int n = 3000;
  RowMatrixXf points(n, kDim);
  for (int i = 0; i < n; ++i) points.row(i) = RandomUnit(rng).transpose();
  auto tree = std::make_shared<const VocabularyTree>(
      VocabularyTree::Train(points, VocabularyTreeOptions()));
  VocabularyTreeIndex tree_index(tree);
  ExhaustiveIndex exhaustive(kDim);
  for (int i = 0; i < n; ++i) {
    tree_index.Insert(1000 + i, points.row(i).transpose());
    exhaustive.Insert(1000 + i, points.row(i).transpose());
  }
  REQUIRE(tree_index.Size() == n);
  const int num_queries = 500;
  int same_top1 = 0;
  double overlap30 = 0;
  std::uniform_int_distribution<int> pick(0, n - 1);
  for (int q = 0; q < num_queries; ++q) {
    const Eigen::VectorXf query =
        (points.row(pick(rng)).transpose() + 0.7f * RandomUnit(rng)).normalized();
    const auto exact = exhaustive.Query(query, 30);
    const auto approx = tree_index.Query(query, 30);
    REQUIRE(exact.size() == 30);
    REQUIRE(approx.size() == 30);
    same_top1 += exact[0].image_id == approx[0].image_id;
    std::set<int> exact_ids;
    for (const auto& c : exact) exact_ids.insert(c.image_id);
    for (const auto& c : approx) overlap30 += exact_ids.count(c.image_id) / 30.0;
  }
  INFO("top-30 overlap " << overlap30 / num_queries);
  CHECK(same_top1 >= 0.95 * num_queries);
}

TEST_CASE("exhaustive index ranks by Euclidean distance") {
  ExhaustiveIndex index(2);
  index.Insert(5, Eigen::Vector2f(0, 0));
  index.Insert(6, Eigen::Vector2f(3, 4));
  index.Insert(7, Eigen::Vector2f(1, 0));
  const auto result = index.Query(Eigen::Vector2f(0.9f, 0), 2);
  REQUIRE(result.size() == 2);
  CHECK(result[0].image_id == 7);
  CHECK(result[0].distance == Approx(0.1).margin(1e-6));
  CHECK(result[1].image_id == 5);
  CHECK(index.Query(Eigen::Vector2f(0, 0), 10).size() == 3);
  CHECK(index.DescriptorOf(6) == Eigen::Vector2f(3, 4));
  CHECK_THROWS_AS(index.Insert(5, Eigen::Vector2f(1, 1)), std::invalid_argument);
  CHECK_THROWS_AS(index.Insert(8, Eigen::Vector3f(1, 1, 1)), std::invalid_argument);
  CHECK_THROWS_AS(index.Query(Eigen::Vector3f(1, 1, 1), 1), std::invalid_argument);
  CHECK_THROWS_AS(index.DescriptorOf(9), std::invalid_argument);
}

TEST_CASE("a tree query widens until it has N candidates") {
  // Few images in a big tree: most leaves are empty, yet every query returns
  // all inserted images when N exceeds their number.
  std::mt19937 rng(8);
  RowMatrixXf points(2000, kDim);
  for (int i = 0; i < 2000; ++i) points.row(i) = RandomUnit(rng).transpose();
  auto tree = std::make_shared<const VocabularyTree>(
      VocabularyTree::Train(points, VocabularyTreeOptions()));
  VocabularyTreeIndex index(tree);
  for (int i = 0; i < 12; ++i) index.Insert(i, RandomUnit(rng));
  const auto result = index.Query(RandomUnit(rng), 30);
  CHECK(result.size() == 12);
  CHECK(std::is_sorted(result.begin(), result.end(),
                       [](const auto& a, const auto& b) { return a.distance < b.distance; }));
  CHECK(index.Query(RandomUnit(rng), 0).empty());
}

}  // namespace
}  // namespace flysfm
