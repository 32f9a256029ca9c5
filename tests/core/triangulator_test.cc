#include "core/triangulator.h"

#include <catch2/catch.hpp>

#include "tests/testing/scene_model.h"

namespace flysfm {
namespace {

using testing::SceneImageId;
using testing::SceneModel;

// Ten cameras on a 60 degree arc around 500 points: neighbours see the
// scene under about 6.7 degrees.
testing::SyntheticScene ArcScene() {
  testing::SyntheticSceneOptions options;
  options.seed = 3;
  return testing::MakeSyntheticScene(options);
}

Triangulator::ColorFunction NoColor() {
  return [](const TrackElement&) { return std::array<std::uint8_t, 3>{0, 0, 0}; };
}

// The scene point a model point observes, through one of its observations.
int ScenePointOf(const SceneModel& model, const Point3D& point) {
  const TrackElement& element = point.track.front();
  const std::vector<point2D_t>& keypoints = model.keypoint[element.image_id - 1];
  for (std::size_t p = 0; p < keypoints.size(); ++p) {
    if (keypoints[p] == element.point2D_idx) return int(p);
  }
  return -1;
}

// A scene point the first `num_images` images all see.
int PointSeenByImages(const SceneModel& model, int num_images) {
  for (std::size_t p = 0; p < model.keypoint.front().size(); ++p) {
    if (std::all_of(model.keypoint.begin(), model.keypoint.begin() + num_images,
                    [&](const auto& k) { return k[p] != kInvalidPoint2DIdx; })) {
      return int(p);
    }
  }
  FAIL("no point seen by all of the first images");
  return -1;
}

TEST_CASE("New tracks are exact and continue into later images") {
  const testing::SyntheticScene scene = ArcScene();
  SceneModel model = testing::MakeSceneModel(scene);
  Triangulator triangulator(Triangulator::Options(), &model.matches, &model.reconstruction,
                            NoColor());
  testing::RegisterAtTruePose(scene, 0, &model);
  testing::RegisterAtTruePose(scene, 1, &model);
  const Triangulator::Summary first = triangulator.TriangulateImage(SceneImageId(1));
  CHECK(first.num_new_points > 300);
  CHECK(first.num_continued == 0);
  CHECK(int(model.reconstruction.NumPoints3D()) == first.num_new_points);
  for (const auto& [id, point] : model.reconstruction.points3D()) {
    CHECK((point.xyz - scene.points[ScenePointOf(model, point)]).norm() < 1e-6);
  }

  testing::RegisterAtTruePose(scene, 2, &model);
  const Triangulator::Summary second = triangulator.TriangulateImage(SceneImageId(2));
  // Every point the first pair made and image 2 sees is continued, not made
  // again: one physical point, one 3D point.
  CHECK(second.num_continued > 300);
  std::vector<int> points_per_scene_point(scene.points.size(), 0);
  for (const auto& [id, point] : model.reconstruction.points3D()) {
    ++points_per_scene_point[ScenePointOf(model, point)];
  }
  CHECK(*std::max_element(points_per_scene_point.begin(), points_per_scene_point.end()) == 1);
}

// One scene point seen by images 0-4 lives twice in the model: seen by images
// 0-1 at its position + offset1 and, apart, by 2-3 at + offset2. Image 4 is
// then registered and triangulated.
struct TwoCopies {
  testing::SyntheticScene scene = ArcScene();
  SceneModel model = testing::MakeSceneModel(scene);
  int p = -1;
  point3D_t a = kInvalidPoint3DId;
  point3D_t b = kInvalidPoint3DId;
  Triangulator::Summary summary;

  TwoCopies(const Eigen::Vector3d& offset1, const Eigen::Vector3d& offset2) {
    for (int i = 0; i < 4; ++i) testing::RegisterAtTruePose(scene, i, &model);
    p = PointSeenByImages(model, 5);
    const auto element = [&](int image) {
      return TrackElement{SceneImageId(image), model.keypoint[image][p]};
    };
    a = model.reconstruction.AddPoint3D(scene.points[p] + offset1, {element(0), element(1)});
    b = model.reconstruction.AddPoint3D(scene.points[p] + offset2, {element(2), element(3)});
    testing::RegisterAtTruePose(scene, 4, &model);
    Triangulator triangulator(Triangulator::Options(), &model.matches, &model.reconstruction,
                              NoColor());
    summary = triangulator.TriangulateImage(SceneImageId(4));
  }
};

TEST_CASE("Two points that are one are merged through the new image's matches") {
  // Each copy 1 mm off: a tenth of a pixel at 5 m and f = 500.
  const TwoCopies copies(Eigen::Vector3d(0.001, 0, 0), Eigen::Vector3d(-0.001, 0, 0));
  CHECK(copies.summary.num_merged == 1);
  const Reconstruction& model = copies.model.reconstruction;
  const bool a_survives = model.ExistsPoint3D(copies.a);
  CHECK(a_survives != model.ExistsPoint3D(copies.b));
  const Point3D& merged = model.point3D(a_survives ? copies.a : copies.b);
  CHECK(merged.track.size() == 5);
  CHECK((merged.xyz - copies.scene.points[copies.p]).norm() < 0.001);
}

TEST_CASE("Two points too far apart to be one are not merged") {
  // The second copy 20 cm off across the line of sight: the merged position
  // would lie 10 cm (about 10 px at 5 m and f = 500) from each, past the
  // threshold of 2 px.
  const TwoCopies copies(Eigen::Vector3d::Zero(), Eigen::Vector3d(0.2, 0, 0));
  CHECK(copies.summary.num_merged == 0);
  CHECK(copies.model.reconstruction.ExistsPoint3D(copies.a));
  CHECK(copies.model.reconstruction.ExistsPoint3D(copies.b));
}

TEST_CASE("A pair too close to triangulate gets another try with a third ray") {
  const testing::SyntheticScene scene = ArcScene();
  SceneModel model = testing::MakeSceneModel(scene);
  // Image 2 is matched with image 1 only; images 0 and 1 are 6.7 degrees
  // apart, under the 10 degrees asked for here.
  model.matches.SetMatches(SceneImageId(0), SceneImageId(2), {});
  Triangulator::Options options;
  options.triangulation.min_tri_angle_deg = 10;
  Triangulator triangulator(options, &model.matches, &model.reconstruction, NoColor());
  testing::RegisterAtTruePose(scene, 0, &model);
  testing::RegisterAtTruePose(scene, 1, &model);
  // Only the odd point near the cameras sees them under 10 degrees.
  CHECK(triangulator.TriangulateImage(SceneImageId(1)).num_new_points < 25);
  // Image 2's rays meet image 0's, through image 1's matches, at 13 degrees.
  testing::RegisterAtTruePose(scene, 2, &model);
  const Triangulator::Summary summary = triangulator.TriangulateImage(SceneImageId(2));
  CHECK(summary.num_new_points > 300);
  for (const auto& [id, point] : model.reconstruction.points3D()) {
    CHECK(point.track.size() == 3);
    CHECK((point.xyz - scene.points[ScenePointOf(model, point)]).norm() < 1e-6);
  }
}

TEST_CASE("Tracks are completed with matched keypoints of other registered images") {
  const testing::SyntheticScene scene = ArcScene();
  // Images 0 and 1 make the points; image 2 registered but never
  // triangulated, so its keypoints observe nothing yet. Image 3 sees the
  // points and is matched to all three: the tracks it continues pick up
  // image 2 through its matches, unless completion is off.
  const auto image3_completes = [&](bool complete_and_merge_tracks, SceneModel* model) {
    for (int i = 0; i < 3; ++i) testing::RegisterAtTruePose(scene, i, model);
    Triangulator::Options options;
    options.complete_and_merge_tracks = complete_and_merge_tracks;
    Triangulator triangulator(options, &model->matches, &model->reconstruction, NoColor());
    model->matches.SetMatches(SceneImageId(0), SceneImageId(2), {});
    model->matches.SetMatches(SceneImageId(1), SceneImageId(2), {});
    triangulator.TriangulateImage(SceneImageId(1));
    CHECK(model->reconstruction.image(SceneImageId(2)).num_points3D == 0);
    testing::RegisterAtTruePose(scene, 3, model);
    return triangulator.TriangulateImage(SceneImageId(3)).num_completed;
  };
  SceneModel model = testing::MakeSceneModel(scene);
  CHECK(image3_completes(true, &model) > 300);
  CHECK(model.reconstruction.image(SceneImageId(2)).num_points3D > 300);
  SceneModel without = testing::MakeSceneModel(scene);
  CHECK(image3_completes(false, &without) == 0);
  CHECK(without.reconstruction.image(SceneImageId(2)).num_points3D == 0);
}

}  // namespace
}  // namespace flysfm
