#include "core/initializer.h"

#include <cmath>

#include <catch2/catch.hpp>

#include "geometry/essential_matrix.h"
#include "geometry/fundamental_matrix.h"
#include "tests/testing/scene_model.h"

namespace flysfm {
namespace {

using testing::SceneImageId;
using testing::SceneModel;

TwoViewGeometry TrueGeometry(const testing::SyntheticScene& scene, int image1, int image2) {
  TwoViewGeometry geometry;
  geometry.config = TwoViewConfiguration::kCalibrated;
  geometry.has_pose = true;
  geometry.cam2_from_cam1 =
      scene.cams_from_world[image2] * Inverse(scene.cams_from_world[image1]);
  return geometry;
}

TEST_CASE("The initial pair is the one with most well-triangulated points, not most matches") {
  testing::SyntheticSceneOptions options;
  options.seed = 4;
  const testing::SyntheticScene scene = testing::MakeSyntheticScene(options);
  SceneModel model = testing::MakeSceneModel(scene);
  // Pair (0, 3): 20 degrees, its true matches cut to 150 and padded with 300
  // wrong ones (matched keypoints of different points), 450 in all. Pair
  // (0, 5): 33 degrees, 300 true matches.
  const image_t id0 = SceneImageId(0);
  std::vector<FeatureMatch> matches03 = model.matches.Matches(id0, SceneImageId(3));
  std::vector<FeatureMatch> matches05 = model.matches.Matches(id0, SceneImageId(5));
  REQUIRE(matches03.size() >= 450);
  REQUIRE(matches05.size() >= 300);
  matches05.resize(300);
  for (int i = 150; i < 450; ++i) matches03[i].idx2 = matches03[(i + 37) % 450].idx2;
  matches03.resize(450);
  model.matches.SetMatches(id0, SceneImageId(3), matches03);
  model.matches.SetMatches(id0, SceneImageId(5), matches05);

  Initializer initializer(Initializer::Options{});
  initializer.AddPair(id0, SceneImageId(3), TrueGeometry(scene, 0, 3), true);
  initializer.AddPair(id0, SceneImageId(5), TrueGeometry(scene, 0, 5), true);
  const std::vector<InitialPair> ranked =
      initializer.RankPairs(model.reconstruction, model.matches);
  REQUIRE(ranked.size() == 2);
  CHECK(ranked[0].image_id2 == SceneImageId(5));
  CHECK(ranked[0].num_points == 300);
  // The wrong matches of (0, 3) almost never meet within 4 px.
  CHECK(ranked[1].num_points >= 150);
  CHECK(ranked[1].num_points < 200);
  CHECK(ranked[0].median_tri_angle_deg > ranked[1].median_tri_angle_deg);

  // A discarded pair is not ranked again; a pair without enough points is
  // never ranked.
  initializer.Discard(ranked[0]);
  CHECK(initializer.RankPairs(model.reconstruction, model.matches).size() == 1);
  Initializer::Options strict;
  strict.min_num_points = 301;
  Initializer demanding(strict);
  demanding.AddPair(id0, SceneImageId(5), TrueGeometry(scene, 0, 5), true);
  CHECK(demanding.RankPairs(model.reconstruction, model.matches).empty());
}

TEST_CASE("A pair without a pose, a pure rotation, or F with known intrinsics cannot start a model") {
  const testing::SyntheticScene scene = testing::MakeSyntheticScene({});
  SceneModel model = testing::MakeSceneModel(scene);
  Initializer initializer(Initializer::Options{});
  TwoViewGeometry no_pose = TrueGeometry(scene, 0, 4);
  no_pose.has_pose = false;
  TwoViewGeometry panoramic = TrueGeometry(scene, 0, 5);
  panoramic.config = TwoViewConfiguration::kPanoramic;
  initializer.AddPair(SceneImageId(0), SceneImageId(4), no_pose, false);
  initializer.AddPair(SceneImageId(0), SceneImageId(5), panoramic, false);
  CHECK(initializer.RankPairs(model.reconstruction, model.matches).empty());
  // F preferred to E: a start only while the intrinsics are a guess.
  TwoViewGeometry uncalibrated = TrueGeometry(scene, 0, 3);
  uncalibrated.config = TwoViewConfiguration::kUncalibrated;
  initializer.AddPair(SceneImageId(0), SceneImageId(3), uncalibrated, true);
  CHECK(initializer.RankPairs(model.reconstruction, model.matches).empty());
  initializer.AddPair(SceneImageId(0), SceneImageId(3), uncalibrated, false);
  CHECK(initializer.RankPairs(model.reconstruction, model.matches).size() == 1);
  Initializer::Options bad;
  bad.min_num_points = 1;
  CHECK_FALSE(bad.Check());
  CHECK_THROWS_AS(Initializer(bad), std::invalid_argument);
}

// Without a calibration: F of the pair in pixels, and E's pose as the guessed
// focal length distorts it (here: no rotation, the baseline along x).
TwoViewGeometry GuessedGeometry(const testing::SyntheticScene& scene, int image1, int image2) {
  TwoViewGeometry geometry = TrueGeometry(scene, image1, image2);
  geometry.config = TwoViewConfiguration::kUncalibrated;
  const Eigen::Matrix3d K = CalibrationMatrix(scene.camera);
  geometry.F = FundamentalFromEssential(EssentialFromPose(geometry.cam2_from_cam1), K, K);
  geometry.cam2_from_cam1 = Rigid3d(Eigen::Quaterniond::Identity(), Eigen::Vector3d::UnitX());
  return geometry;
}

// Cameras tilted by up to 15 deg: their optical axes pass each other, so that
// F fixes the focal length (geometry/focal_from_fundamental).
TEST_CASE("A focal length guessed twice too long is corrected from the pairs' F, and the poses follow") {
  testing::SyntheticSceneOptions options;
  options.max_tilt_deg = 15;
  options.seed = 7;
  const testing::SyntheticScene scene = testing::MakeSyntheticScene(options);
  SceneModel model = testing::MakeSceneModel(scene);
  const camera_t camera_id = model.reconstruction.image(SceneImageId(0)).camera_id;
  Initializer initializer(Initializer::Options{});
  for (const int other : {3, 6}) {
    initializer.AddPair(SceneImageId(0), SceneImageId(other), GuessedGeometry(scene, 0, other),
                        false);
  }
  // The true focal length (500 px): nothing to correct.
  double focal_length = 0;
  CHECK(initializer.CorrectFocalLength(model.reconstruction, camera_id, &focal_length) == 0);

  model.reconstruction.camera(camera_id).SetFocalLength(1000);
  REQUIRE(initializer.CorrectFocalLength(model.reconstruction, camera_id, &focal_length) == 1);
  CHECK(std::abs(focal_length / 500 - 1) < 1e-6);
  model.reconstruction.camera(camera_id).SetFocalLength(focal_length);
  initializer.RecomputePoses(model.reconstruction, model.matches);
  const std::vector<InitialPair> ranked =
      initializer.RankPairs(model.reconstruction, model.matches);
  REQUIRE(ranked.size() == 2);
  for (const InitialPair& pair : ranked) {
    const Rigid3d truth = scene.cams_from_world[pair.image_id2 - SceneImageId(0)] *
                          Inverse(scene.cams_from_world[0]);
    CHECK(pair.cam2_from_cam1.rotation.angularDistance(truth.rotation) < 1e-6);
    CHECK(pair.cam2_from_cam1.translation.normalized().dot(truth.translation.normalized()) >
          1 - 1e-9);
    // Exact observations: every match triangulates.
    CHECK(pair.num_points ==
          int(model.matches.Matches(SceneImageId(0), pair.image_id2).size()));
  }
}

TEST_CASE("Pairs where GRIC chose H, or cameras that look at one point, correct no focal length") {
  testing::SyntheticSceneOptions options;
  options.max_tilt_deg = 0;
  const testing::SyntheticScene scene = testing::MakeSyntheticScene(options);
  SceneModel model = testing::MakeSceneModel(scene);
  const camera_t camera_id = model.reconstruction.image(SceneImageId(0)).camera_id;
  model.reconstruction.camera(camera_id).SetFocalLength(1000);
  Initializer initializer(Initializer::Options{});
  initializer.AddPair(SceneImageId(0), SceneImageId(4), GuessedGeometry(scene, 0, 4), false);
  double focal_length = 0;
  CHECK(initializer.CorrectFocalLength(model.reconstruction, camera_id, &focal_length) == 0);

  testing::SyntheticSceneOptions tilted = options;
  tilted.max_tilt_deg = 15;
  const testing::SyntheticScene tilted_scene = testing::MakeSyntheticScene(tilted);
  TwoViewGeometry geometry = GuessedGeometry(tilted_scene, 0, 4);
  Initializer from_f(Initializer::Options{});
  from_f.AddPair(SceneImageId(0), SceneImageId(4), geometry, false);
  CHECK(from_f.CorrectFocalLength(model.reconstruction, camera_id, &focal_length) == 1);
  geometry.config = TwoViewConfiguration::kPlanar;
  Initializer from_h(Initializer::Options{});
  from_h.AddPair(SceneImageId(0), SceneImageId(4), geometry, false);
  CHECK(from_h.CorrectFocalLength(model.reconstruction, camera_id, &focal_length) == 0);
}

}  // namespace
}  // namespace flysfm
