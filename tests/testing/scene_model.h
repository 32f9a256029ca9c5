#pragma once

// Synthetic scenes as the engine's steps meet them: images with keypoints and
// pairwise matches, before anything registers (core's tests and benches).

#include <unordered_map>
#include <vector>

#include "bundle/association_tree.h"
#include "core/scene/reconstruction.h"
#include "matching/match_store.h"
#include "tests/testing/scene_reconstruction.h"

namespace flysfm::testing {

// The scene as the engine's steps meet it before anything registers: every
// image with its observations as keypoints (in the same order as above), no
// pose and no point; every pair of images matched on the points they share.
// Quadratic in the images: for small scenes.
struct SceneModel {
  Reconstruction reconstruction;
  MatchStore matches;
  // keypoint[i][p]: the keypoint of scene point p in scene image i, or
  // kInvalidPoint2DIdx where the image does not see it.
  std::vector<std::vector<point2D_t>> keypoint;
};
SceneModel MakeSceneModel(const SyntheticScene& scene);

// Registers scene image i of the model at its true pose.
void RegisterAtTruePose(const SyntheticScene& scene, int image, SceneModel* model);

// The Eq. 4 weights of a tree built over scene image indices, keyed by image
// id as AdjustLocalBundle takes them.
std::unordered_map<image_t, double> SceneImageWeights(
    const HierarchicalAssociationTree& tree);

}  // namespace flysfm::testing
