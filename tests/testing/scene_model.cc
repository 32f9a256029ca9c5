#include "tests/testing/scene_model.h"

#include <string>

namespace flysfm::testing {

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
