#include "tests/testing/scene_reconstruction.h"

#include <string>

namespace flysfm::testing {

SceneReconstruction ReconstructionFromScene(const SyntheticScene& scene) {
  SceneReconstruction held;
  Reconstruction& r = held.reconstruction;
  const camera_t camera_id = r.AddCamera(scene.camera);
  const int num_images = static_cast<int>(scene.cams_from_world.size());
  // One pass over the observations: a scene of thousands of images holds
  // millions of them.
  std::vector<std::vector<Eigen::Vector2d>> keypoints(num_images);
  std::vector<std::vector<TrackElement>> tracks(scene.points.size());
  for (const SyntheticObservation& obs : scene.observations) {
    tracks[obs.point].push_back(
        {SceneImageId(obs.image), point2D_t(keypoints[obs.image].size())});
    keypoints[obs.image].push_back(obs.pixel);
  }
  for (int i = 0; i < num_images; ++i) {
    r.AddImage("image" + std::to_string(i), camera_id, keypoints[i], SceneImageId(i));
    r.RegisterImage(SceneImageId(i), scene.cams_from_world[i]);
  }
  held.point_ids.assign(scene.points.size(), kInvalidPoint3DId);
  for (std::size_t p = 0; p < scene.points.size(); ++p) {
    if (tracks[p].size() >= 2) held.point_ids[p] = r.AddPoint3D(scene.points[p], tracks[p]);
  }
  return held;
}

}  // namespace flysfm::testing
