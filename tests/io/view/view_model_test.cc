#include "io/view/view_model.h"

#include <limits>
#include <set>

#include <catch2/catch.hpp>
#include <nlohmann/json.hpp>

#include "tests/testing/scene_reconstruction.h"
#include "tests/testing/synthetic.h"

namespace flysfm {
namespace {

Reconstruction SceneModel() {
  testing::SyntheticSceneOptions options;
  options.num_images = 5;
  options.num_points = 150;
  return testing::ReconstructionFromScene(testing::MakeSyntheticScene(options)).reconstruction;
}

ViewLine Line(const std::string& name, ImageStatus status, const std::string& reason = "") {
  ImageResult result;
  result.name = name;
  result.status = status;
  result.reason = reason;
  return MakeViewLine(result, std::nullopt);
}

// The snapshot's arrays say the same as the model: each id once, at its
// own position.
void CheckMirrors(const ViewSnapshot& snapshot, const Reconstruction& model) {
  REQUIRE(snapshot.point_ids.size() == model.NumPoints3D());
  REQUIRE(snapshot.xyz.size() == 3 * snapshot.point_ids.size());
  REQUIRE(snapshot.rgb.size() == 3 * snapshot.point_ids.size());
  std::set<point3D_t> seen;
  for (std::size_t i = 0; i < snapshot.point_ids.size(); ++i) {
    const point3D_t id = snapshot.point_ids[i];
    CHECK(seen.insert(id).second);
    REQUIRE(model.ExistsPoint3D(id));
    for (int k = 0; k < 3; ++k) {
      CHECK(snapshot.xyz[3 * i + k] == Approx(model.point3D(id).xyz[k]).margin(1e-5));
    }
  }
  CHECK(snapshot.cameras.size() == model.NumRegisteredImages());
}

TEST_CASE("An update carries the changed points and cameras only") {
  Reconstruction model = SceneModel();
  model.TakeChanges();
  const point3D_t moved = model.points3D().begin()->first;
  model.point3D(moved).xyz += Eigen::Vector3d(0, 0, 1);
  model.MarkPointChanged(moved);
  const image_t image = testing::SceneImageId(1);
  model.RegisterImage(image, *model.image(image).cam_from_world);

  const ViewUpdate update = MakeViewUpdate(model, model.TakeChanges(), {});
  CHECK(update.point_ids == std::vector<point3D_t>{moved});
  CHECK(update.xyz.size() == 3);
  CHECK(update.xyz[2] == Approx(model.point3D(moved).xyz.z()));
  REQUIRE(update.cameras.size() == 1);
  CHECK(update.cameras[0].image_id == image);
  CHECK(update.removed_points.empty());
  CHECK(update.intrinsics.empty());
  CHECK(update.num_points == int(model.NumPoints3D()));
  CHECK(update.num_images == 5);
}

TEST_CASE("The view's copy follows the model through additions and moves and removals") {
  Reconstruction model = SceneModel();
  ViewModel view;
  view.Apply(MakeViewUpdate(model, model.TakeChanges(), {}));
  CheckMirrors(view.snapshot(), model);

  // Remove every third point (swap-remove fills their slots from the end),
  // move some others, deregister an image.
  std::vector<point3D_t> ids;
  for (const auto& [id, point] : model.points3D()) ids.push_back(id);
  for (std::size_t i = 0; i < ids.size(); ++i) {
    if (i % 3 == 0) {
      model.DeletePoint3D(ids[i]);
    } else if (i % 3 == 1) {
      model.point3D(ids[i]).xyz *= 2;
      model.MarkPointChanged(ids[i]);
    }
  }
  model.DeRegisterImage(testing::SceneImageId(4));
  const ViewUpdate update = MakeViewUpdate(model, model.TakeChanges(), {});
  CHECK(update.removed_cameras == std::vector<image_t>{testing::SceneImageId(4)});
  view.Apply(update);
  CheckMirrors(view.snapshot(), model);
}

// The snapshot's measures are the tracker's, slot by slot.
void CheckQualityMirrors(const ViewSnapshot& snapshot, const QualityTracker& quality) {
  REQUIRE(snapshot.quality.views.size() == snapshot.point_ids.size());
  REQUIRE(snapshot.quality.max_angle_deg.size() == snapshot.point_ids.size());
  REQUIRE(snapshot.quality.sigma.size() == snapshot.point_ids.size());
  for (std::size_t i = 0; i < snapshot.point_ids.size(); ++i) {
    const std::optional<PointQuality> expected = quality.Point(snapshot.point_ids[i]);
    REQUIRE(expected);
    CHECK(snapshot.quality.views[i] == expected->views);
    CHECK(snapshot.quality.max_angle_deg[i] == Approx(expected->max_angle_deg).epsilon(1e-6));
    REQUIRE(expected->sigma);
    CHECK(snapshot.quality.sigma[i] == Approx(*expected->sigma).epsilon(1e-6));
  }
}

TEST_CASE("Points carry their quality measures, and the copy keeps them at their slots") {
  Reconstruction model = SceneModel();
  QualityTracker quality;
  Reconstruction::Changes changes = model.TakeChanges();
  quality.Update(model, changes);
  ViewModel view;
  const ViewUpdate first = MakeViewUpdate(model, changes, {}, &quality);
  REQUIRE(first.coverage_rule);
  CHECK(first.coverage_rule->min_views == quality.options().min_views);
  CHECK(first.coverage_rule->min_angle_deg == quality.options().min_angle_deg);
  REQUIRE(first.quality.views.size() == first.point_ids.size());
  view.Apply(first);
  CheckMirrors(view.snapshot(), model);
  CheckQualityMirrors(view.snapshot(), quality);
  // Five views around the scene: each point seen by all of them.
  CHECK(view.snapshot().quality.views.front() == 5);

  // Removals fill slots from the end; a deregistered image takes a view from
  // every point it saw.
  std::vector<point3D_t> ids;
  for (const auto& [id, point] : model.points3D()) ids.push_back(id);
  for (std::size_t i = 0; i < ids.size(); i += 4) model.DeletePoint3D(ids[i]);
  model.DeRegisterImage(testing::SceneImageId(4));
  changes = model.TakeChanges();
  quality.Update(model, changes);
  // As the run loop does: the points measured again are sent too.
  Reconstruction::Changes remeasured;
  remeasured.changed_points.insert(quality.LastRecomputedPoints().begin(),
                                   quality.LastRecomputedPoints().end());
  changes.Merge(remeasured);
  view.Apply(MakeViewUpdate(model, changes, {}, &quality));
  CheckMirrors(view.snapshot(), model);
  CheckQualityMirrors(view.snapshot(), quality);
  CHECK(view.snapshot().quality.views.front() == 4);

  const nlohmann::json m = nlohmann::json::parse(ModelMessage(view.snapshot()));
  CHECK(m["coverage"]["min_views"] == quality.options().min_views);
  CHECK(m["points"]["views"].size() == model.NumPoints3D());
  CHECK(m["points"]["angle"].size() == model.NumPoints3D());
  CHECK(m["points"]["sigma"].size() == model.NumPoints3D());
}

TEST_CASE("An undefined uncertainty is sent as null, and a run without measures sends none") {
  ViewUpdate update;
  update.point_ids = {1, 2};
  update.xyz = {0, 0, 1, 0, 1, 1};
  update.rgb = {1, 2, 3, 4, 5, 6};
  const nlohmann::json bare = nlohmann::json::parse(UpdateMessage(update, nullptr));
  CHECK_FALSE(bare["points"].contains("views"));
  CHECK_FALSE(bare.contains("coverage"));
  update.quality.views = {1, 3};
  update.quality.max_angle_deg = {0, 12.5f};
  update.quality.sigma = {std::numeric_limits<float>::quiet_NaN(), 0.25f};
  update.coverage_rule = ViewCoverageRule{3, 10};
  const nlohmann::json u = nlohmann::json::parse(UpdateMessage(update, nullptr));
  CHECK(u["points"]["views"] == nlohmann::json({1, 3}));
  CHECK(u["points"]["sigma"][0].is_null());
  CHECK(u["points"]["sigma"][1] == 0.25);
  CHECK(u["coverage"]["min_angle_deg"] == 10.0);
}

TEST_CASE("The surface and its suggestions go in the update that carries them and stay for a page opened later") {
  ViewSurface surface;
  surface.xyz = {0, 0, 1, 1, 0, 1, 0, 1, 1};
  surface.classes = {std::uint8_t(Coverage::FaceClass::kFewViews)};
  surface.well_covered_share = 0.25;
  surface.area = 0.5;
  surface.suggestions.push_back({Eigen::Quaterniond::Identity(), Eigen::Vector3d(1, 2, 3), 0.75,
                                 "75 % of the surface, on the back, seen by fewer than 3 photos"});
  ViewUpdate update;
  update.surface = surface;
  ViewModel view;
  view.Apply(update);
  const nlohmann::json u = nlohmann::json::parse(UpdateMessage(update, nullptr));
  CHECK(u["surface"]["classes"] == nlohmann::json({2}));
  CHECK(u["surface"]["xyz"].size() == 9);
  CHECK(u["surface"]["share"] == 0.25);
  CHECK(u["surface"]["suggestions"][0]["t"] == nlohmann::json({1.0, 2.0, 3.0}));
  CHECK(u["surface"]["suggestions"][0]["q"][3] == 1.0);
  CHECK(u["surface"]["suggestions"][0]["reason"] == surface.suggestions[0].reason);
  // A later update without a surface leaves the page's as it was.
  view.Apply(ViewUpdate());
  CHECK_FALSE(nlohmann::json::parse(UpdateMessage(ViewUpdate(), nullptr)).contains("surface"));
  const nlohmann::json m = nlohmann::json::parse(ModelMessage(view.snapshot()));
  CHECK(m["surface"]["suggestions"].size() == 1);
  CHECK(m["surface"]["area"] == 0.5);
}

TEST_CASE("Pending and rejected lists follow the per-image lines") {
  ViewModel view;
  ViewUpdate update;
  update.lines = {Line("a.jpg", ImageStatus::kPending, "too few matches"),
                  Line("b.jpg", ImageStatus::kRejected, "cannot decode")};
  CHECK(view.Apply(update));
  CHECK(view.snapshot().pending.at("a.jpg") == "too few matches");
  CHECK(view.snapshot().rejected.at("b.jpg") == "cannot decode");
  update.lines = {Line("a.jpg", ImageStatus::kRegistered)};
  CHECK(view.Apply(update));
  CHECK(view.snapshot().pending.empty());
  CHECK(view.snapshot().latest->name == "a.jpg");
  update.lines = {Line("c.jpg", ImageStatus::kRegistered)};
  CHECK_FALSE(view.Apply(update));
}

TEST_CASE("A line carries the tag of its image's source") {
  ImageResult result;
  result.name = "alice/IMG_0001.JPG";
  result.status = ImageStatus::kRegistered;
  ViewUpdate update;
  update.lines = {MakeViewLine(result, std::nullopt, "alice")};
  const nlohmann::json u = nlohmann::json::parse(UpdateMessage(update, nullptr));
  CHECK(u["lines"][0]["source"] == "alice");
  CHECK(u["lines"][0]["name"] == "alice/IMG_0001.JPG");
}

TEST_CASE("While there are sub-models, lines and cameras say which, and a merge is told") {
  ImageResult result;
  result.name = "bob/IMG_0003.JPG";
  result.status = ImageStatus::kRegistered;
  CHECK(MakeViewLine(result, std::nullopt).model.empty());  // one model: nothing to tell
  result.model_id = 2;
  result.num_models = 3;
  CHECK(MakeViewLine(result, std::nullopt).model == "sub-model 2 of 3");
  result.num_models = 2;
  result.num_merged_models = 1;
  ViewUpdate update;
  update.lines = {MakeViewLine(result, std::nullopt)};
  ViewCamera camera;
  camera.image_id = 4;
  camera.camera_id = 1;
  camera.model_id = 2;
  update.cameras = {camera};
  const nlohmann::json u = nlohmann::json::parse(UpdateMessage(update, nullptr));
  CHECK(u["lines"][0]["model"] == "sub-model 2 of 2, merged 1");
  CHECK(u["cameras"][0]["model"] == 2);
}

TEST_CASE("Messages are one line of valid JSON whatever the names and numbers") {
  ViewModel view;
  ViewUpdate update;
  update.lines = {Line("we\"ird\nname\xff.jpg", ImageStatus::kPending, "tab\there")};
  update.point_ids = {7, 9};
  update.xyz = {1.5f, -2.0f, std::numeric_limits<float>::quiet_NaN(), 0, 0, 1e30f};
  update.rgb = {255, 0, 10, 1, 2, 3};
  ViewCamera camera;
  camera.image_id = 3;
  camera.camera_id = 1;
  camera.name = "c.jpg";
  camera.translation = Eigen::Vector3d(1, 2, 3);
  update.cameras = {camera};
  update.intrinsics = {{1, 500.0, 640, 480}};
  update.num_images = 1;
  update.num_points = 2;
  const bool lists_changed = view.Apply(update);
  view.Finish();

  const std::string update_text = UpdateMessage(update, lists_changed ? &view.snapshot() : nullptr);
  const std::string model_text = ModelMessage(view.snapshot());
  for (const std::string& text : {update_text, model_text, EndMessage()}) {
    CHECK(text.find('\n') == std::string::npos);
  }
  const nlohmann::json u = nlohmann::json::parse(update_text);
  CHECK(u["type"] == "update");
  CHECK(u["points"]["ids"] == nlohmann::json({7, 9}));
  CHECK(u["points"]["xyz"][2].is_null());
  CHECK(u["points"]["rgb"][0] == 255);
  CHECK(u["pending"].size() == 1);
  CHECK(u["counts"]["points"] == 2);
  CHECK(u["lines"][0]["source"] == "");
  const nlohmann::json m = nlohmann::json::parse(model_text);
  CHECK(m["type"] == "model");
  CHECK(m["finished"] == true);
  CHECK(m["cameras"][0]["t"] == nlohmann::json({1.0, 2.0, 3.0}));
  CHECK(m["cameras"][0]["q"][3] == 1.0);
  CHECK(m["intrinsics"][0]["focal"] == 500.0);
  CHECK(m["points"]["ids"].size() == 2);
  CHECK(m["line"]["reason"] == "tab\there");
  CHECK(nlohmann::json::parse(EndMessage())["type"] == "end");
}

}  // namespace
}  // namespace flysfm
