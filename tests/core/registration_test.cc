#include "core/registration.h"

#include <set>

#include <catch2/catch.hpp>

#include "tests/testing/scene_model.h"

namespace flysfm {
namespace {

using testing::SceneImageId;
using testing::SceneModel;

// Images 0 and 1 registered at their true poses, observing every point they
// both see at its true position.
SceneModel TwoViewModel(const testing::SyntheticScene& scene) {
  SceneModel model = testing::MakeSceneModel(scene);
  testing::RegisterAtTruePose(scene, 0, &model);
  testing::RegisterAtTruePose(scene, 1, &model);
  for (std::size_t p = 0; p < scene.points.size(); ++p) {
    const point2D_t k0 = model.keypoint[0][p];
    const point2D_t k1 = model.keypoint[1][p];
    if (k0 == kInvalidPoint2DIdx || k1 == kInvalidPoint2DIdx) continue;
    model.reconstruction.AddPoint3D(scene.points[p],
                                    {{SceneImageId(0), k0}, {SceneImageId(1), k1}});
  }
  return model;
}

TEST_CASE("2D-3D correspondences follow the neighbours' tracks, one per keypoint and point") {
  const testing::SyntheticScene scene = testing::MakeSyntheticScene({});
  SceneModel model = TwoViewModel(scene);
  const image_t id2 = SceneImageId(2);
  const std::map<model_t, std::vector<Correspondence2D3D>> per_model =
      Find2D3DCorrespondences(model.reconstruction, model.matches, id2);
  REQUIRE(per_model.size() == 1);
  REQUIRE(per_model.count(Reconstruction::kFirstModelId) == 1);
  const std::vector<Correspondence2D3D>& correspondences = per_model.begin()->second;
  REQUIRE(correspondences.size() > 300);
  std::set<point2D_t> keypoints;
  std::set<point3D_t> points;
  for (const Correspondence2D3D& c : correspondences) {
    keypoints.insert(c.point2D_idx);
    points.insert(c.point3D_id);
    CHECK(c.pixel == model.reconstruction.image(id2).points2D[c.point2D_idx].xy);
    // The keypoint sees the very point it is matched to.
    const Eigen::Vector3d& xyz = model.reconstruction.point3D(c.point3D_id).xyz;
    CHECK((scene.camera.ImgFromCam(scene.cams_from_world[2] * xyz) - c.pixel).norm() < 1e-9);
  }
  CHECK(keypoints.size() == correspondences.size());
  CHECK(points.size() == correspondences.size());
}

TEST_CASE("The registrar registers an image at its pose with its inlier observations") {
  const testing::SyntheticScene scene = testing::MakeSyntheticScene({});
  SceneModel model = TwoViewModel(scene);
  LsmImageStore lsm_images({});
  Registrar::Options options;
  options.lsm_densification = false;  // no pixels in this scene
  Registrar registrar(options, &model.matches, &model.reconstruction, &lsm_images);
  StageTimes times;
  const image_t id2 = SceneImageId(2);
  const Registrar::Result result = registrar.Register(id2, &times);
  REQUIRE(result.success);
  const Image& image = model.reconstruction.image(id2);
  REQUIRE(image.IsRegistered());
  const Rigid3d& truth = scene.cams_from_world[2];
  CHECK(image.cam_from_world->rotation.angularDistance(truth.rotation) < 1e-6);
  CHECK((image.cam_from_world->translation - truth.translation).norm() < 1e-6);
  CHECK(result.num_pose_inliers == result.num_correspondences);
  CHECK(image.num_points3D == result.num_pose_inliers);
  CHECK(times.registration > 0);

  // Too few correspondences: a reason, and nothing registered.
  options.min_num_correspondences = 10000;
  Registrar strict(options, &model.matches, &model.reconstruction, &lsm_images);
  const Registrar::Result refused = strict.Register(SceneImageId(3), &times);
  CHECK_FALSE(refused.success);
  CHECK(refused.reason.find("too few") != std::string::npos);
  CHECK_FALSE(model.reconstruction.image(SceneImageId(3)).IsRegistered());
}

}  // namespace
}  // namespace flysfm
