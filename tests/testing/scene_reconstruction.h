#pragma once

// Synthetic scenes held in core's Reconstruction, for the tests and benches of
// code that works on the model as the engine builds it.

#include <unordered_map>
#include <vector>

#include "bundle/association_tree.h"
#include "core/reconstruction.h"
#include "matching/match_store.h"
#include "tests/testing/synthetic.h"

namespace flysfm::testing {

// Image i of a scene is image id i + 1 of its reconstruction (ids start at 1,
// as in COLMAP).
inline image_t SceneImageId(int image) { return static_cast<image_t>(image + 1); }

struct SceneReconstruction {
  Reconstruction reconstruction;
  // Per scene point, its id in `reconstruction`; kInvalidPoint3DId for a
  // point seen by fewer than two images, which cannot form a track.
  std::vector<point3D_t> point_ids;
};

// The scene at its ground truth: one camera; every image registered at its
// true pose, with its observations as keypoints (in the scene's order); every point
// seen at least twice, with its full track.
SceneReconstruction ReconstructionFromScene(const SyntheticScene& scene);

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
