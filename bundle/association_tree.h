#pragma once

// The paper's hierarchical association tree (Sect. III-D, Fig. 7) and its
// ripple weights (Eq. 4). The caller builds the local bundle from its own
// scene, its images weighted by WeightOf (the engine: core/scene_bundle.h).

#include <functional>
#include <unordered_map>
#include <vector>

namespace flysfm {

class HierarchicalAssociationTree {
 public:
  struct Options {
    // Neighbours taken from each image's ranked retrieval list. The paper's
    // 8 comes from photo sets; in a video the top-8 of the top-8 are mostly
    // new images again, and ripple 2 alone held 12 or more: top-5 halves the
    // refined block (about 12 images) at the same ATE on fr1_xyz.
    int top_n = 5;
    // Number of ripples L. Ripple L is held fixed, so L = 3 is the smallest
    // depth with two weighted ripples (p = 1, k) inside a fixed border; on a
    // survey path with top-8 neighbours it holds 25 - 35 images, about 20 of
    // them refined, which solves in about 50 ms (docs/bundle.md).
    int depth = 3;
    // Ratio k > 1 between the weights of successive ripples (paper: 2).
    // k = 1 with `fix_outermost_ripple` false is an ordinary local BA.
    double k = 2.0;
    bool fix_outermost_ripple = true;

    bool Check() const;
    // Eq. 4: 1 for the new image (ripple 0), k^(i-1) for ripple i < L,
    // infinity for ripple L when it is fixed (else k^(L-1)).
    double Weight(int ripple) const;
  };

  // Ids of the registered images most similar to an image, best first (from
  // retrieval). Only the first `top_n` are used.
  using NeighbourFunction = std::function<std::vector<int>(int image_id)>;

  // Breadth-first from the new image: ripple i holds the top-N neighbours of
  // ripple i-1 that appear in no earlier ripple. Ripples may end early when
  // the neighbours run out.
  static HierarchicalAssociationTree Build(int new_image_id,
                                           const NeighbourFunction& neighbours,
                                           const Options& options);

  const Options& options() const { return options_; }
  int NewImage() const { return ripples_.front().front(); }
  // ripples()[0] is {new image}; ripples()[i] the images first seen at depth i.
  const std::vector<std::vector<int>>& ripples() const { return ripples_; }
  // Ripple of an image, -1 when it is not in the tree.
  int RippleOf(int image_id) const;
  // Eq. 4 weight of an image of the tree.
  double WeightOf(int image_id) const { return options_.Weight(RippleOf(image_id)); }
  int NumImages() const { return static_cast<int>(ripple_of_.size()); }

 private:
  Options options_;
  std::vector<std::vector<int>> ripples_;
  std::unordered_map<int, int> ripple_of_;
};

}  // namespace flysfm
