#include "retrieval/vocabulary_tree.h"

#include <fstream>
#include <queue>
#include <stdexcept>

#include "geometry/check.h"
#include "retrieval/binary_io.h"
#include "retrieval/kmeans.h"

namespace flysfm {
namespace {

constexpr char kTreeMagic[9] = "FSVTREE1";
constexpr std::uint32_t kTreeVersion = 1;

float SquaredDistance(const float* a, const float* b, int dim) {
  return (Eigen::Map<const Eigen::VectorXf>(a, dim) - Eigen::Map<const Eigen::VectorXf>(b, dim))
      .squaredNorm();
}

}  // namespace

bool VocabularyTreeOptions::Check() const {
  return branching >= 2 && depth >= 1 && kmeans_iterations >= 1;
}

VocabularyTree VocabularyTree::Train(const RowMatrixXf& points,
                                     const VocabularyTreeOptions& options) {
  if (!options.Check()) throw std::invalid_argument("invalid VocabularyTreeOptions");
  if (points.rows() < 1) throw std::invalid_argument("vocabulary tree needs training points");
  VocabularyTree tree;
  tree.branching_ = options.branching;
  tree.depth_ = options.depth;

  // Breadth-first, so every node's children are contiguous.
  struct Pending {
    int node;
    int level;
    std::vector<int> members;
  };
  std::vector<Eigen::VectorXf> centres{points.colwise().mean().transpose()};
  tree.nodes_.emplace_back();
  std::queue<Pending> queue;
  {
    std::vector<int> all(points.rows());
    for (int i = 0; i < int(all.size()); ++i) all[i] = i;
    queue.push({0, 0, std::move(all)});
  }
  KMeansOptions kmeans;
  kmeans.num_iterations = options.kmeans_iterations;
  while (!queue.empty()) {
    Pending item = std::move(queue.front());
    queue.pop();
    if (item.level == options.depth || int(item.members.size()) <= options.branching) {
      tree.nodes_[item.node].leaf = tree.num_leaves_++;
      continue;
    }
    RowMatrixXf subset(item.members.size(), points.cols());
    for (int k = 0; k < int(item.members.size()); ++k) subset.row(k) = points.row(item.members[k]);
    kmeans.seed = options.seed + std::uint32_t(item.node);
    std::vector<int> assignment;
    const RowMatrixXf children = KMeans(subset, options.branching, kmeans, &assignment);
    if (children.rows() < 2) {  // all members identical: nothing to split
      tree.nodes_[item.node].leaf = tree.num_leaves_++;
      continue;
    }
    const int first = int(tree.nodes_.size());
    tree.nodes_[item.node].first_child = first;
    tree.nodes_[item.node].num_children = int(children.rows());
    std::vector<std::vector<int>> members(children.rows());
    for (int k = 0; k < int(assignment.size()); ++k) {
      members[assignment[k]].push_back(item.members[k]);
    }
    for (int c = 0; c < int(children.rows()); ++c) {
      tree.nodes_.emplace_back();
      centres.push_back(children.row(c).transpose());
      queue.push({first + c, item.level + 1, std::move(members[c])});
    }
  }
  tree.centres_.resize(centres.size(), points.cols());
  for (int k = 0; k < int(centres.size()); ++k) tree.centres_.row(k) = centres[k].transpose();
  return tree;
}

int VocabularyTree::FindLeaf(const float* descriptor) const {
  FLYSFM_CHECK(!nodes_.empty());
  int node = 0;
  while (nodes_[node].leaf < 0) {
    const Node& n = nodes_[node];
    int best = n.first_child;
    float best_d = SquaredDistance(descriptor, centres_.row(best).data(), Dim());
    for (int c = n.first_child + 1; c < n.first_child + n.num_children; ++c) {
      const float d = SquaredDistance(descriptor, centres_.row(c).data(), Dim());
      if (d < best_d) {
        best_d = d;
        best = c;
      }
    }
    node = best;
  }
  return nodes_[node].leaf;
}

void VocabularyTree::VisitLeavesBestFirst(const float* descriptor,
                                          const std::function<bool(int leaf)>& visit) const {
  FLYSFM_CHECK(!nodes_.empty());
  using Entry = std::pair<float, int>;  // (squared distance, node)
  std::priority_queue<Entry, std::vector<Entry>, std::greater<Entry>> queue;
  queue.push({0.f, 0});
  while (!queue.empty()) {
    const int node = queue.top().second;
    queue.pop();
    const Node& n = nodes_[node];
    if (n.leaf >= 0) {
      if (!visit(n.leaf)) return;
      continue;
    }
    for (int c = n.first_child; c < n.first_child + n.num_children; ++c) {
      queue.push({SquaredDistance(descriptor, centres_.row(c).data(), Dim()), c});
    }
  }
}

void VocabularyTree::Write(std::ostream& out) const {
  WriteHeader(out, kTreeMagic, kTreeVersion);
  WriteValue(out, std::int32_t(branching_));
  WriteValue(out, std::int32_t(depth_));
  WriteValue(out, std::int32_t(num_leaves_));
  WriteValue(out, std::int32_t(nodes_.size()));
  for (const Node& n : nodes_) {
    WriteValue(out, n.first_child);
    WriteValue(out, n.num_children);
    WriteValue(out, n.leaf);
  }
  WriteMatrix(out, centres_);
}

VocabularyTree VocabularyTree::Read(std::istream& in) {
  ReadHeader(in, kTreeMagic, kTreeVersion);
  VocabularyTree tree;
  tree.branching_ = ReadValue<std::int32_t>(in, "tree branching");
  tree.depth_ = ReadValue<std::int32_t>(in, "tree depth");
  tree.num_leaves_ = ReadValue<std::int32_t>(in, "tree leaf count");
  const auto num_nodes = ReadValue<std::int32_t>(in, "tree node count");
  if (tree.branching_ < 2 || tree.depth_ < 1 || num_nodes < 1 || num_nodes > (1 << 26) ||
      tree.num_leaves_ < 1 || tree.num_leaves_ > num_nodes) {
    throw std::runtime_error("corrupt vocabulary tree: bad sizes");
  }
  tree.nodes_.resize(num_nodes);
  int leaves = 0;
  for (int k = 0; k < num_nodes; ++k) {
    Node& n = tree.nodes_[k];
    n.first_child = ReadValue<std::int32_t>(in, "tree node");
    n.num_children = ReadValue<std::int32_t>(in, "tree node");
    n.leaf = ReadValue<std::int32_t>(in, "tree node");
    // Children come after their parent, so a walk from the root always ends.
    const bool leaf_ok = n.leaf >= 0 && n.leaf < tree.num_leaves_ && n.num_children == 0;
    const bool inner_ok = n.leaf == -1 && n.num_children >= 1 && n.first_child > k &&
                          n.num_children <= tree.branching_ &&
                          n.first_child + n.num_children <= num_nodes;
    if (!leaf_ok && !inner_ok) throw std::runtime_error("corrupt vocabulary tree: bad node");
    if (leaf_ok) ++leaves;
  }
  if (leaves != tree.num_leaves_) throw std::runtime_error("corrupt vocabulary tree: leaf count");
  tree.centres_ = ReadMatrix(in, "tree centres");
  if (tree.centres_.rows() != num_nodes || tree.centres_.cols() < 1) {
    throw std::runtime_error("corrupt vocabulary tree: centre count");
  }
  return tree;
}

void VocabularyTree::Save(const std::string& path) const {
  std::ofstream out(path, std::ios::binary);
  if (!out) throw std::runtime_error("cannot write vocabulary tree '" + path + "'");
  Write(out);
  if (!out) throw std::runtime_error("error writing vocabulary tree '" + path + "'");
}

VocabularyTree VocabularyTree::Load(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw std::runtime_error("cannot open vocabulary tree '" + path + "'");
  try {
    return Read(in);
  } catch (const std::runtime_error& e) {
    throw std::runtime_error("'" + path + "': " + e.what());
  }
}

bool VocabularyTree::operator==(const VocabularyTree& other) const {
  if (branching_ != other.branching_ || depth_ != other.depth_ ||
      num_leaves_ != other.num_leaves_ || nodes_.size() != other.nodes_.size() ||
      !IdenticalMatrices(centres_, other.centres_)) {
    return false;
  }
  for (std::size_t k = 0; k < nodes_.size(); ++k) {
    const Node &a = nodes_[k], &b = other.nodes_[k];
    if (a.first_child != b.first_child || a.num_children != b.num_children || a.leaf != b.leaf) {
      return false;
    }
  }
  return true;
}

}  // namespace flysfm
