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

// The scene held as two sub-models, as a chain of shots that broke leaves
// them: images 0 .. num_first - 1 at their true poses in
// Reconstruction::kFirstModelId, the others in a second sub-model whose frame
// is `second_from_world`; each point split into the parts of its track in
// each (those with two observations or more).
struct TwoSubModelScene {
  Reconstruction reconstruction;
  model_t second_id = kInvalidModelId;
  Sim3d second_from_world;
  // Per scene point, its id in each sub-model (kInvalidPoint3DId: none).
  std::vector<point3D_t> first_ids;
  std::vector<point3D_t> second_ids;
};
TwoSubModelScene TwoSubModelsFromScene(const SyntheticScene& scene, int num_first,
                                       const Sim3d& second_from_world);

}  // namespace flysfm::testing
