#include "bundle/association_tree.h"

#include <cmath>
#include <map>
#include <vector>

#include <catch2/catch.hpp>

namespace flysfm {
namespace {

using Tree = HierarchicalAssociationTree;

TEST_CASE("Each image joins the ripple where it first appears") {
  // 0 is new; its ranked neighbours are 1, 2, 3; theirs overlap.
  const std::map<int, std::vector<int>> graph = {
      {0, {1, 2, 3}}, {1, {2, 4, 0, 9}}, {2, {5, 1}}, {3, {4, 6}},
      {4, {7}},       {5, {8}},          {6, {}},     {7, {}}, {8, {}}};
  const Tree::NeighbourFunction neighbours = [&](int id) { return graph.at(id); };
  Tree::Options options;
  options.top_n = 2;
  options.depth = 3;
  const Tree tree = Tree::Build(0, neighbours, options);

  REQUIRE(tree.ripples().size() == 4);
  CHECK(tree.ripples()[0] == std::vector<int>{0});
  // Only the top two of each list: 3 and 9 are cut off.
  CHECK(tree.ripples()[1] == std::vector<int>{1, 2});
  CHECK(tree.ripples()[2] == std::vector<int>{4, 5});
  CHECK(tree.ripples()[3] == std::vector<int>{7, 8});
  CHECK(tree.NewImage() == 0);
  CHECK(tree.NumImages() == 7);
  CHECK(tree.RippleOf(2) == 1);
  CHECK(tree.RippleOf(3) == -1);
  CHECK(tree.RippleOf(9) == -1);

  SECTION("and the tree stops when the neighbours run out") {
    options.depth = 6;
    CHECK(Tree::Build(0, neighbours, options).ripples().size() == 4);
  }
}

TEST_CASE("Ripple weights follow Eq. 4") {
  Tree::Options options;
  options.depth = 4;
  CHECK(options.Weight(0) == 1.0);
  CHECK(options.Weight(1) == 1.0);
  CHECK(options.Weight(2) == 2.0);
  CHECK(options.Weight(3) == 4.0);
  CHECK(std::isinf(options.Weight(4)));
  options.k = 1.0;
  options.fix_outermost_ripple = false;
  for (int ripple = 0; ripple <= options.depth; ++ripple) {
    CHECK(options.Weight(ripple) == 1.0);
  }
  CHECK(options.Check());
  options.k = 0.5;
  CHECK_FALSE(options.Check());
  options.k = 2;
  options.top_n = 0;
  CHECK_FALSE(options.Check());
}

}  // namespace
}  // namespace flysfm
