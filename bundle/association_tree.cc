#include "bundle/association_tree.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "geometry/check.h"

namespace flysfm {

bool HierarchicalAssociationTree::Options::Check() const {
  return top_n >= 1 && depth >= 1 && std::isfinite(k) && k >= 1.0;
}

double HierarchicalAssociationTree::Options::Weight(int ripple) const {
  FLYSFM_CHECK(ripple >= 0 && ripple <= depth);
  if (ripple == 0) return 1.0;
  if (ripple == depth && fix_outermost_ripple) {
    return std::numeric_limits<double>::infinity();
  }
  return std::pow(k, ripple - 1);
}

HierarchicalAssociationTree HierarchicalAssociationTree::Build(
    int new_image_id, const NeighbourFunction& neighbours,
    const Options& options) {
  FLYSFM_CHECK(options.Check());
  HierarchicalAssociationTree tree;
  tree.options_ = options;
  tree.ripples_.push_back({new_image_id});
  tree.ripple_of_[new_image_id] = 0;
  for (int ripple = 1; ripple <= options.depth; ++ripple) {
    std::vector<int> next;
    for (const int parent : tree.ripples_.back()) {
      const std::vector<int> ranked = neighbours(parent);
      const int n = std::min<int>(options.top_n, static_cast<int>(ranked.size()));
      for (int j = 0; j < n; ++j) {
        if (tree.ripple_of_.emplace(ranked[j], ripple).second) {
          next.push_back(ranked[j]);
        }
      }
    }
    if (next.empty()) break;
    tree.ripples_.push_back(std::move(next));
  }
  return tree;
}

int HierarchicalAssociationTree::RippleOf(int image_id) const {
  const auto it = ripple_of_.find(image_id);
  return it == ripple_of_.end() ? -1 : it->second;
}

}  // namespace flysfm
