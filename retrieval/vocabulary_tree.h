#pragma once

// A vocabulary tree over global descriptors (Nister & Stewenius 2006, used on
// global CNN features by the on-the-fly SfM paper): hierarchical k-means with
// `branching` children per node, `depth` levels. Only the tree is here; the
// images inserted into its leaves live in VocabularyTreeIndex (image_index.h).

#include <cstdint>
#include <functional>
#include <istream>
#include <ostream>
#include <string>
#include <vector>

#include "retrieval/types.h"

namespace flysfm {

struct VocabularyTreeOptions {
  // The paper's values: 5 children per node, 5 levels (3 125 leaves at most).
  int branching = 5;
  int depth = 5;
  int kmeans_iterations = 10;
  std::uint32_t seed = 0;

  bool Check() const;
};

class VocabularyTree {
 public:
  // Hierarchical k-means on the rows of `points` (at least one). A node with
  // no more points than `branching` is not split further, so a small
  // training set gives a smaller tree. Bad options: std::invalid_argument.
  static VocabularyTree Train(const RowMatrixXf& points, const VocabularyTreeOptions& options);

  int Dim() const { return int(centres_.cols()); }
  int NumNodes() const { return int(nodes_.size()); }
  int NumLeaves() const { return num_leaves_; }
  int Branching() const { return branching_; }
  int Depth() const { return depth_; }

  // The leaf (0 .. NumLeaves() - 1) reached by descending to the nearest
  // child at every level.
  int FindLeaf(const float* descriptor) const;

  // Visits leaves best-bin-first: nodes are expanded in order of the distance
  // of the descriptor to their centre, so the first leaf is FindLeaf's and
  // the next ones are those of the nearest neighbouring branches. Stops when
  // `visit` returns false or every leaf has been visited.
  void VisitLeavesBestFirst(const float* descriptor,
                            const std::function<bool(int leaf)>& visit) const;

  // Versioned binary format ("FSVTREE1" tag, version, sizes, nodes, centres).
  // Read and Load throw std::runtime_error on a missing, truncated or corrupt
  // file.
  void Write(std::ostream& out) const;
  static VocabularyTree Read(std::istream& in);
  void Save(const std::string& path) const;
  static VocabularyTree Load(const std::string& path);

  bool operator==(const VocabularyTree& other) const;

 private:
  struct Node {
    // Children are nodes first_child .. first_child + num_children - 1.
    std::int32_t first_child = -1;
    std::int32_t num_children = 0;
    // -1 for inner nodes.
    std::int32_t leaf = -1;
  };

  int branching_ = 0;
  int depth_ = 0;
  int num_leaves_ = 0;
  std::vector<Node> nodes_;  // node 0 is the root
  // One row per node (the root's is the mean of all training points).
  RowMatrixXf centres_;
};

}  // namespace flysfm
