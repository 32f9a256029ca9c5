#pragma once

// Synthetic scenes held in the scene library's Reconstruction at their ground
// truth, for the tests and benches of code that reads or writes the model.

#include <vector>

#include "core/scene/reconstruction.h"
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

}  // namespace flysfm::testing
