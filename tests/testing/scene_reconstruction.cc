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

TwoSubModelScene TwoSubModelsFromScene(const SyntheticScene& scene, int num_first,
                                       const Sim3d& second_from_world) {
  SceneReconstruction held = ReconstructionFromScene(scene);
  TwoSubModelScene two;
  Reconstruction& r = held.reconstruction;
  std::vector<std::vector<TrackElement>> tracks(scene.points.size());
  for (std::size_t p = 0; p < scene.points.size(); ++p) {
    if (held.point_ids[p] == kInvalidPoint3DId) continue;
    tracks[p] = r.point3D(held.point_ids[p]).track;
    r.DeletePoint3D(held.point_ids[p]);
  }
  two.second_id = r.NewModelId();
  two.second_from_world = second_from_world;
  for (int i = num_first; i < int(scene.cams_from_world.size()); ++i) {
    r.RegisterImage(SceneImageId(i), TransformPose(second_from_world, scene.cams_from_world[i]),
                    two.second_id);
  }
  two.first_ids.assign(scene.points.size(), kInvalidPoint3DId);
  two.second_ids.assign(scene.points.size(), kInvalidPoint3DId);
  for (std::size_t p = 0; p < scene.points.size(); ++p) {
    std::vector<TrackElement> first_part, second_part;
    for (const TrackElement& element : tracks[p]) {
      (element.image_id < SceneImageId(num_first) ? first_part : second_part).push_back(element);
    }
    if (first_part.size() >= 2) two.first_ids[p] = r.AddPoint3D(scene.points[p], first_part);
    if (second_part.size() >= 2) {
      two.second_ids[p] = r.AddPoint3D(second_from_world * scene.points[p], second_part);
    }
  }
  two.reconstruction = std::move(r);
  return two;
}

}  // namespace flysfm::testing
