#pragma once

// A synthetic scene (synthetic.h) as the engine's model sees it before any
// image registers: each image with one keypoint per observation, and every
// pair of images matched on the points they share. Tests register images at
// their true poses and run the engine's steps on exact data.

#include <vector>

#include "core/reconstruction.h"
#include "matching/match_store.h"
#include "tests/testing/synthetic.h"

namespace flysfm::testing {

struct SceneModel {
  Reconstruction reconstruction;
  MatchStore matches;
  // Image id of scene image i (ids start at 1, as in the engine).
  static image_t ImageId(int image) { return image_t(image + 1); }
  // keypoint[i][p]: the keypoint of scene point p in scene image i, or
  // kInvalidPoint2DIdx where the image does not see it.
  std::vector<std::vector<point2D_t>> keypoint;
};

SceneModel MakeSceneModel(const SyntheticScene& scene);

// Registers scene image i at its true pose.
void RegisterAtTruePose(const SyntheticScene& scene, int image, SceneModel* model);

}  // namespace flysfm::testing
