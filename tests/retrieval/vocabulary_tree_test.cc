#include "retrieval/vocabulary_tree.h"

#include <filesystem>
#include <fstream>
#include <random>
#include <set>
#include <sstream>
#include <stdexcept>

#include <catch2/catch.hpp>

#include "tests/testing/temp_dir.h"

namespace flysfm {
namespace {

RowMatrixXf RandomPoints(int n, int dim, std::uint32_t seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<float> normal(0.f, 1.f);
  RowMatrixXf points(n, dim);
  for (int i = 0; i < n; ++i) {
    for (int d = 0; d < dim; ++d) points(i, d) = normal(rng);
    points.row(i).normalize();
  }
  return points;
}

TEST_CASE("a trained tree has the requested shape and visits every leaf once") {
  const RowMatrixXf points = RandomPoints(4000, 32, 1);
  const VocabularyTree tree = VocabularyTree::Train(points, VocabularyTreeOptions());
  CHECK(tree.Branching() == 5);
  CHECK(tree.Depth() == 5);
  CHECK(tree.Dim() == 32);
  // 4 000 points cannot fill 3 125 leaves with more than 5 points each, so
  // some branches stop early, but the tree is deep and wide.
  CHECK(tree.NumLeaves() > 500);
  CHECK(tree.NumLeaves() <= 3125);
  for (int i = 0; i < 20; ++i) {
    std::vector<int> order;
    tree.VisitLeavesBestFirst(points.row(i).data(), [&](int leaf) {
      order.push_back(leaf);
      return true;
    });
    REQUIRE(int(order.size()) == tree.NumLeaves());
    REQUIRE(std::set<int>(order.begin(), order.end()).size() == order.size());
    REQUIRE(order.front() == tree.FindLeaf(points.row(i).data()));
  }
  // Stopping early.
  int visited = 0;
  tree.VisitLeavesBestFirst(points.row(0).data(), [&](int) { return ++visited < 3; });
  CHECK(visited == 3);
}

TEST_CASE("a small training set gives a small tree") {
  const RowMatrixXf points = RandomPoints(3, 8, 2);
  const VocabularyTree tree = VocabularyTree::Train(points, VocabularyTreeOptions());
  CHECK(tree.NumLeaves() == 1);
  CHECK(tree.FindLeaf(points.row(0).data()) == 0);
}

TEST_CASE("tree save and load round-trip exactly") {
  const VocabularyTree tree =
      VocabularyTree::Train(RandomPoints(2000, 64, 3), VocabularyTreeOptions());
  const std::string path = (testing::MakeTempDir("vocabulary_tree_test") / "tree.bin").string();
  tree.Save(path);
  const VocabularyTree loaded = VocabularyTree::Load(path);
  CHECK(loaded == tree);
  const RowMatrixXf queries = RandomPoints(50, 64, 4);
  for (int i = 0; i < 50; ++i) {
    REQUIRE(loaded.FindLeaf(queries.row(i).data()) == tree.FindLeaf(queries.row(i).data()));
  }

  // Truncations and a wrong tag are clear errors.
  std::ifstream in(path, std::ios::binary);
  const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  for (const std::size_t size : {std::size_t(0), std::size_t(5), std::size_t(30), bytes.size() / 2,
                                 bytes.size() - 1}) {
    std::istringstream cut(bytes.substr(0, size));
    REQUIRE_THROWS_AS(VocabularyTree::Read(cut), std::runtime_error);
  }
  std::string wrong = bytes;
  wrong[0] = 'X';
  std::istringstream wrong_stream(wrong);
  CHECK_THROWS_AS(VocabularyTree::Read(wrong_stream), std::runtime_error);
  CHECK_THROWS_AS(VocabularyTree::Load(path + ".missing"), std::runtime_error);
  std::filesystem::remove(path);
}

TEST_CASE("bad tree options are rejected") {
  VocabularyTreeOptions options;
  options.branching = 1;
  CHECK_FALSE(options.Check());
  CHECK_THROWS_AS(VocabularyTree::Train(RandomPoints(10, 4, 5), options), std::invalid_argument);
}

}  // namespace
}  // namespace flysfm
