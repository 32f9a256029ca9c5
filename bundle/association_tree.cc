#include "bundle/association_tree.h"

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

LocalBundle ExtractLocalBundle(const BundleProblem& source,
                               const HierarchicalAssociationTree& tree) {
  const int num_images = static_cast<int>(source.images.size());
  const int num_points = static_cast<int>(source.points.size());
  constexpr int kNone = -1;

  LocalBundle local;
  local.problem.cameras = source.cameras;
  std::vector<int> local_image(num_images, kNone);
  // Refined images first, in ripple order.
  for (const std::vector<int>& ripple : tree.ripples()) {
    for (const int id : ripple) {
      FLYSFM_CHECK(id >= 0 && id < num_images);
      const double weight = tree.WeightOf(id);
      if (std::isinf(weight) || source.images[id].constant_pose) continue;
      BundleImage image = source.images[id];
      image.weight = weight;
      local_image[id] = static_cast<int>(local.problem.images.size());
      local.problem.images.push_back(image);
      local.source_image.push_back(id);
    }
  }

  std::vector<int> local_point(num_points, kNone);
  for (const BundleObservation& obs : source.observations) {
    if (local_image[obs.image] == kNone || local_point[obs.point] != kNone) continue;
    local_point[obs.point] = static_cast<int>(local.problem.points.size());
    local.problem.points.push_back(source.points[obs.point]);
    local.source_point.push_back(obs.point);
  }

  for (const BundleObservation& obs : source.observations) {
    const int point = local_point[obs.point];
    if (point == kNone) continue;
    int& image = local_image[obs.image];
    if (image == kNone) {
      BundleImage constant = source.images[obs.image];
      constant.constant_pose = true;
      constant.weight = 1.0;
      image = static_cast<int>(local.problem.images.size());
      local.problem.images.push_back(constant);
      local.source_image.push_back(obs.image);
    }
    local.problem.observations.push_back({image, point, obs.pixel});
  }
  return local;
}

void WriteBack(const LocalBundle& local, BundleProblem* source) {
  FLYSFM_CHECK(source != nullptr);
  source->cameras = local.problem.cameras;
  for (size_t i = 0; i < local.source_image.size(); ++i) {
    if (local.problem.images[i].constant_pose) continue;
    source->images[local.source_image[i]].cam_from_world =
        local.problem.images[i].cam_from_world;
  }
  for (size_t p = 0; p < local.source_point.size(); ++p) {
    source->points[local.source_point[p]] = local.problem.points[p];
  }
}

}  // namespace flysfm
