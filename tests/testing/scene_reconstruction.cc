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

SceneModel MakeSceneModel(const SyntheticScene& scene) {
  SceneModel model;
  const int num_images = int(scene.cams_from_world.size());
  const camera_t camera_id = model.reconstruction.AddCamera(scene.camera);
  model.keypoint.assign(num_images,
                        std::vector<point2D_t>(scene.points.size(), kInvalidPoint2DIdx));
  for (int i = 0; i < num_images; ++i) {
    std::vector<Eigen::Vector2d> keypoints;
    for (const SyntheticObservation& observation : scene.ObservationsOf(i)) {
      model.keypoint[i][observation.point] = point2D_t(keypoints.size());
      keypoints.push_back(observation.pixel);
    }
    model.reconstruction.AddImage("image" + std::to_string(i), camera_id, keypoints,
                                  SceneImageId(i));
  }
  for (int i = 0; i < num_images; ++i) {
    for (int j = i + 1; j < num_images; ++j) {
      std::vector<FeatureMatch> matches;
      for (std::size_t p = 0; p < scene.points.size(); ++p) {
        if (model.keypoint[i][p] != kInvalidPoint2DIdx &&
            model.keypoint[j][p] != kInvalidPoint2DIdx) {
          matches.push_back({int(model.keypoint[i][p]), int(model.keypoint[j][p])});
        }
      }
      model.matches.SetMatches(SceneImageId(i), SceneImageId(j),
                               std::move(matches));
    }
  }
  return model;
}

void RegisterAtTruePose(const SyntheticScene& scene, int image, SceneModel* model) {
  model->reconstruction.RegisterImage(SceneImageId(image), scene.cams_from_world[image]);
}

std::unordered_map<image_t, double> SceneImageWeights(
    const HierarchicalAssociationTree& tree) {
  std::unordered_map<image_t, double> weights;
  for (const std::vector<int>& ripple : tree.ripples()) {
    for (const int image : ripple) weights[SceneImageId(image)] = tree.WeightOf(image);
  }
  return weights;
}

}  // namespace flysfm::testing
