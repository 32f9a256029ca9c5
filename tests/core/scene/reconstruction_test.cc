#include "core/scene/reconstruction.h"

#include <algorithm>
#include <sstream>

#include <catch2/catch.hpp>

#include "tests/testing/scene_reconstruction.h"
#include "tests/testing/synthetic.h"

namespace flysfm {
namespace {

testing::SyntheticSceneOptions FixtureOptions(double noise_px = 0.0) {
  testing::SyntheticSceneOptions options;
  options.num_images = 6;
  options.num_points = 200;
  options.noise_px = noise_px;
  return options;
}

// A reconstruction holding a synthetic scene exactly: every image registered
// at its true pose, every point with its full track.
struct Fixture {
  Reconstruction reconstruction;
  std::vector<point3D_t> point_ids;

  explicit Fixture(double noise_px = 0.0) {
    testing::SceneReconstruction held =
        testing::ReconstructionFromScene(testing::MakeSyntheticScene(FixtureOptions(noise_px)));
    reconstruction = std::move(held.reconstruction);
    for (const point3D_t id : held.point_ids) {
      if (id != kInvalidPoint3DId) point_ids.push_back(id);
    }
  }
};

TEST_CASE("A synthetic scene is held with consistent observations") {
  Fixture f;
  const Reconstruction& r = f.reconstruction;
  CHECK(r.NumRegisteredImages() == 6);
  CHECK(r.NumPoints3D() == f.point_ids.size());
  CHECK(r.MeanReprojectionError() < 1e-9);
  std::size_t observed = 0;
  for (const auto& [id, image] : r.images()) {
    int count = 0;
    for (const Point2D& p : image.points2D) count += p.HasPoint3D();
    CHECK(count == image.num_points3D);
    observed += count;
  }
  CHECK(observed == r.NumObservations());
  CHECK(r.MeanTrackLength() == Approx(double(observed) / r.NumPoints3D()));
}

TEST_CASE("Deleting observations keeps both directions consistent") {
  Fixture f;
  Reconstruction& r = f.reconstruction;
  const point3D_t id = f.point_ids.front();
  const std::vector<TrackElement> track = r.point3D(id).track;
  REQUIRE(track.size() >= 3);
  r.DeleteObservation(track[0].image_id, track[0].point2D_idx);
  CHECK(r.point3D(id).track.size() == track.size() - 1);
  CHECK_FALSE(r.image(track[0].image_id).points2D[track[0].point2D_idx].HasPoint3D());
  // Down to one observation, the point goes and frees its last keypoint.
  for (std::size_t i = 1; i + 1 < track.size(); ++i) {
    r.DeleteObservation(track[i].image_id, track[i].point2D_idx);
  }
  CHECK_FALSE(r.ExistsPoint3D(id));
  CHECK_FALSE(r.image(track.back().image_id).points2D[track.back().point2D_idx].HasPoint3D());
}

TEST_CASE("Filtering drops observations over the reprojection threshold") {
  Fixture f;
  Reconstruction& r = f.reconstruction;
  const point3D_t id = f.point_ids[3];
  const TrackElement moved = r.point3D(id).track[0];
  r.image(moved.image_id).points2D[moved.point2D_idx].xy += Eigen::Vector2d(5, 0);
  const std::size_t track_length = r.point3D(id).track.size();
  CHECK(r.ReprojectionError(moved.image_id, moved.point2D_idx, r.point3D(id).xyz) ==
        Approx(5.0));
  CHECK(r.FilterAllPoints3D(/*max_error_px=*/4.0, /*min_angle_deg=*/0.0) == 1);
  CHECK(r.point3D(id).track.size() == track_length - 1);
  CHECK(r.FilterAllPoints3D(4.0, 0.0) == 0);
}

TEST_CASE("Filtering with a bound per image holds each image's observations to its own") {
  Fixture f;
  Reconstruction& r = f.reconstruction;
  const auto keypoint = [&r](const TrackElement& e) -> Point2D& {
    return r.image(e.image_id).points2D[e.point2D_idx];
  };
  const std::vector<TrackElement> track = r.point3D(f.point_ids[3]).track;
  REQUIRE(track.size() >= 3);
  keypoint(track[0]).xy += Eigen::Vector2d(0, 2);
  keypoint(track[1]).xy += Eigen::Vector2d(0, 2);
  // Image 0's bound lets its 2 px through, image 1's does not; images
  // without a bound keep everything.
  const std::unordered_map<image_t, double> bounds = {{track[0].image_id, 3.0},
                                                      {track[1].image_id, 1.0}};
  CHECK(r.FilterPoints3D(f.point_ids, bounds, 0.0) == 1);
  CHECK(keypoint(track[0]).HasPoint3D());
  CHECK_FALSE(keypoint(track[1]).HasPoint3D());
  CHECK(r.FilterPoints3D(f.point_ids, std::unordered_map<image_t, double>(), 0.0) == 0);
}

TEST_CASE("Filtering drops points with too small a triangulation angle") {
  Fixture f;
  Reconstruction& r = f.reconstruction;
  // Cameras span 60 degrees around the scene at 5 units: angles are large.
  const double angle = r.TriangulationAngleDeg(f.point_ids[0]);
  CHECK(angle > 1.0);
  CHECK(r.FilterAllPoints3D(1.0, 0.0) == 0);
  const std::size_t before = r.NumObservations();
  CHECK(r.FilterAllPoints3D(1.0, 180.0) == before);
  CHECK(r.NumPoints3D() == 0);
}

TEST_CASE("Points behind a camera have an infinite error") {
  Fixture f;
  Reconstruction& r = f.reconstruction;
  const TrackElement e = r.point3D(f.point_ids[0]).track[0];
  const Eigen::Vector3d center = ProjectionCenter(*r.image(e.image_id).cam_from_world);
  const Eigen::Vector3d behind = 2 * center - r.point3D(f.point_ids[0]).xyz;
  CHECK(std::isinf(r.ReprojectionError(e.image_id, e.point2D_idx, behind)));
}

TEST_CASE("A moving rolling-shutter image's errors are measured at its rows' times") {
  Fixture f;
  Reconstruction& r = f.reconstruction;
  const TrackElement e = r.point3D(f.point_ids[0]).track[0];
  Image& image = r.image(e.image_id);
  const Eigen::Vector3d xyz = r.point3D(f.point_ids[0]).xyz;
  REQUIRE(r.ReprojectionError(e.image_id, e.point2D_idx, xyz) < 1e-9);
  // Moving at 1 rad/s about y, read out in 30 ms: a row 100 px off the middle
  // is read 6 ms away from it, where the point has moved by about 3 px.
  image.angular_velocity = Eigen::Vector3d(0, 1, 0);
  Camera& camera = r.camera(image.camera_id);
  camera.readout_time = 0.03;
  const double moved = r.ReprojectionError(e.image_id, e.point2D_idx, xyz);
  // A turn by tau about y moves the pixel of normalised (x, y) by
  // f tau (1 + x^2, x y) to first order.
  Eigen::Vector2d& keypoint = image.points2D[e.point2D_idx].xy;
  const double tau = RowTimeFraction(keypoint.y(), camera.height) * camera.readout_time;
  const Eigen::Vector3d in_cam = *image.cam_from_world * xyz;
  const double x = in_cam.x() / in_cam.z(), y = in_cam.y() / in_cam.z();
  CHECK(moved == Approx(std::abs(tau) * camera.MeanFocalLength() *
                        Eigen::Vector2d(1 + x * x, x * y).norm())
                     .epsilon(0.05));
  // Where the moving camera saw it (a fixed point: the row sets the time),
  // the keypoint is exact again.
  for (int i = 0; i < 5; ++i) {
    keypoint = camera.ImgFromCam(camera.InCamAtRow(in_cam, keypoint.y(), image.angular_velocity,
                                                   image.linear_velocity));
  }
  CHECK(r.ReprojectionError(e.image_id, e.point2D_idx, xyz) < 1e-6);
}

TEST_CASE("Merging two points unites their tracks") {
  Fixture f;
  Reconstruction& r = f.reconstruction;
  const point3D_t id = f.point_ids[5];
  const std::vector<TrackElement> track = r.point3D(id).track;
  REQUIRE(track.size() >= 4);
  // Split the track in two points, then merge them back.
  for (std::size_t i = 2; i < track.size(); ++i) {
    r.DeleteObservation(track[i].image_id, track[i].point2D_idx);
  }
  const point3D_t other = r.AddPoint3D(
      r.point3D(id).xyz, std::vector<TrackElement>(track.begin() + 2, track.end()));
  const point3D_t merged = r.MergePoints3D(id, other);
  CHECK_FALSE(r.ExistsPoint3D(other));
  CHECK(r.point3D(merged).track.size() == track.size());
  CHECK(r.MeanReprojectionError() < 1e-9);
}

TEST_CASE("The points two images share are those whose tracks hold both") {
  Fixture f;
  Reconstruction& r = f.reconstruction;
  const auto element_of = [](const Point3D& point, image_t image_id) {
    return std::find_if(point.track.begin(), point.track.end(),
                        [image_id](const TrackElement& e) { return e.image_id == image_id; });
  };
  const auto in_both = [&](image_t a, image_t b) {
    std::size_t count = 0;
    for (const auto& [id, point] : r.points3D()) {
      count += element_of(point, a) != point.track.end() &&
               element_of(point, b) != point.track.end();
    }
    return count;
  };
  const image_t a = r.RegisteredImageIds()[0];
  const image_t b = r.RegisteredImageIds()[3];
  const std::size_t shared = in_both(a, b);
  REQUIRE(shared > 0);
  CHECK(r.NumSharedPoints3D(a, b) == shared);
  CHECK(r.NumSharedPoints3D(b, a) == shared);
  // One observation fewer in `a` of a point both see: one shared point fewer.
  for (const auto& [id, point] : r.points3D()) {
    const auto in_a = element_of(point, a);
    if (point.track.size() < 3 || in_a == point.track.end() ||
        element_of(point, b) == point.track.end()) {
      continue;
    }
    r.DeleteObservation(a, in_a->point2D_idx);
    break;
  }
  CHECK(r.NumSharedPoints3D(a, b) == shared - 1);
  CHECK(r.NumSharedPoints3D(a, b) == in_both(a, b));
  // An image with no points shares none.
  r.DeRegisterImage(b);
  CHECK(r.NumSharedPoints3D(a, b) == 0);
}

TEST_CASE("A similarity transform keeps reprojection errors") {
  Fixture f(0.5);
  Reconstruction& r = f.reconstruction;
  CHECK(r.MeanReprojectionError() == Approx(0.5 * std::sqrt(M_PI / 2)).epsilon(0.15));
  // Rolling-shutter frames too: their motion is in their own frame, its
  // distances scaled with the world.
  r.camera(r.cameras().begin()->first).readout_time = 0.03;
  for (const image_t id : r.RegisteredImageIds()) {
    r.image(id).angular_velocity = Eigen::Vector3d(0.2, -0.5, 0.1);
    r.image(id).linear_velocity = Eigen::Vector3d(0.3, 0.1, -0.4);
  }
  const double before = r.MeanReprojectionError();
  std::mt19937 rng(1);
  r.Transform(Sim3d(3.0, testing::RandomRotation(rng), Eigen::Vector3d(1, -2, 5)));
  CHECK(r.MeanReprojectionError() == Approx(before).epsilon(1e-9));
}

TEST_CASE("Deregistering an image removes its observations") {
  Fixture f;
  Reconstruction& r = f.reconstruction;
  const image_t id = testing::SceneImageId(2);
  r.DeRegisterImage(id);
  CHECK_FALSE(r.image(id).IsRegistered());
  CHECK(r.image(id).num_points3D == 0);
  CHECK(r.NumRegisteredImages() == 5);
  for (const auto& [pid, point] : r.points3D()) {
    for (const auto& e : point.track) CHECK(e.image_id != id);
  }
}

TEST_CASE("TakeChanges reports what changed since the last take and only that") {
  Fixture f;
  Reconstruction& r = f.reconstruction;
  const Reconstruction::Changes built = r.TakeChanges();
  CHECK(built.added_points.size() == r.NumPoints3D());
  CHECK(built.changed_points.empty());  // added wins over the track's additions
  CHECK(built.changed_images.size() == 6);
  CHECK(r.TakeChanges().empty());

  const point3D_t moved = f.point_ids[0];
  const point3D_t gone = f.point_ids[1];
  const std::vector<TrackElement> track = r.point3D(f.point_ids[2]).track;
  REQUIRE(track.size() >= 3);
  r.DeletePoint3D(gone);
  r.point3D(moved).xyz += Eigen::Vector3d(0.1, 0, 0);
  r.MarkPointChanged(moved);
  // Take a point's track away and give it to a new point.
  r.DeletePoint3D(f.point_ids[2]);
  const point3D_t added = r.AddPoint3D(Eigen::Vector3d::Zero(), track);
  // A point added then removed before the take was never visible.
  const point3D_t transient = r.AddPoint3D(Eigen::Vector3d::Zero(), {});
  r.DeletePoint3D(transient);
  const image_t moved_image = testing::SceneImageId(3);
  r.RegisterImage(moved_image, *r.image(moved_image).cam_from_world);

  const Reconstruction::Changes changes = r.TakeChanges();
  CHECK(changes.added_points == std::set<point3D_t>{added});
  CHECK(changes.changed_points == std::set<point3D_t>{moved});
  CHECK(changes.removed_points == std::set<point3D_t>{gone, f.point_ids[2]});
  CHECK(changes.changed_images == std::set<image_t>{moved_image});
  CHECK_FALSE(changes.changed_cameras);

  // Deleting an observation changes the point's track, or removes a point
  // left with one observation.
  const std::vector<TrackElement> added_track = r.point3D(added).track;
  r.DeleteObservation(added_track[0].image_id, added_track[0].point2D_idx);
  CHECK(r.TakeChanges().changed_points == std::set<point3D_t>{added});
  for (std::size_t i = 1; i + 1 < added_track.size(); ++i) {
    r.DeleteObservation(added_track[i].image_id, added_track[i].point2D_idx);
  }
  CHECK(r.TakeChanges().removed_points == std::set<point3D_t>{added});

  r.Transform(Sim3d(2.0, Eigen::Quaterniond::Identity(), Eigen::Vector3d::Zero()));
  const Reconstruction::Changes all = r.TakeChanges();
  CHECK(all.changed_points.size() == r.NumPoints3D());
  CHECK(all.changed_images.size() == r.NumRegisteredImages());
}

TEST_CASE("Two takes merged are the one take of the same edits") {
  const auto first = [](Fixture& f) {
    Reconstruction& r = f.reconstruction;
    r.DeletePoint3D(f.point_ids[1]);
    r.point3D(f.point_ids[0]).xyz += Eigen::Vector3d(0.1, 0, 0);
    r.MarkPointChanged(f.point_ids[0]);
    const std::vector<TrackElement> track = r.point3D(f.point_ids[2]).track;
    r.DeletePoint3D(f.point_ids[2]);
    return r.AddPoint3D(Eigen::Vector3d::Zero(), track);
  };
  const auto second = [](Fixture& f, point3D_t added) {
    Reconstruction& r = f.reconstruction;
    r.DeletePoint3D(added);             // added, then removed: never seen
    r.DeletePoint3D(f.point_ids[0]);    // changed, then removed
    r.MarkPointChanged(f.point_ids[3]);
    const image_t moved_image = testing::SceneImageId(3);
    r.RegisterImage(moved_image, *r.image(moved_image).cam_from_world);
    r.MarkCamerasChanged();
  };
  Fixture one, two;
  one.reconstruction.TakeChanges();
  second(one, first(one));
  const Reconstruction::Changes whole = one.reconstruction.TakeChanges();

  two.reconstruction.TakeChanges();
  const point3D_t added = first(two);
  Reconstruction::Changes merged = two.reconstruction.TakeChanges();
  second(two, added);
  merged.Merge(two.reconstruction.TakeChanges());

  CHECK(merged.added_points == whole.added_points);
  CHECK(merged.changed_points == whole.changed_points);
  CHECK(merged.removed_points == whole.removed_points);
  CHECK(merged.changed_images == whole.changed_images);
  CHECK(merged.changed_cameras == whole.changed_cameras);
  CHECK(merged.removed_points.count(one.point_ids[0]) == 1);
  CHECK(merged.added_points.empty());
}

// The fixture's scene broken in two: images 1-3 in the first sub-model, 4-6
// in a second.
struct TwoSubModels {
  Reconstruction reconstruction;
  model_t second = kInvalidModelId;
  Sim3d second_from_world = Sim3d(
      2.5, Eigen::Quaterniond(Eigen::AngleAxisd(0.7, Eigen::Vector3d(1, 2, 3).normalized())),
      Eigen::Vector3d(4, -1, 9));
  // Per scene point seen by both, its id in the first and in the second.
  std::vector<std::pair<point3D_t, point3D_t>> seen_by_both;
  std::size_t num_observations = 0;

  TwoSubModels() {
    testing::TwoSubModelScene two = testing::TwoSubModelsFromScene(
        testing::MakeSyntheticScene(FixtureOptions()), 3, second_from_world);
    reconstruction = std::move(two.reconstruction);
    second = two.second_id;
    for (std::size_t p = 0; p < two.first_ids.size(); ++p) {
      if (two.first_ids[p] != kInvalidPoint3DId && two.second_ids[p] != kInvalidPoint3DId) {
        seen_by_both.push_back({two.first_ids[p], two.second_ids[p]});
      }
    }
    num_observations = reconstruction.NumObservations();
  }
};

TEST_CASE("Sub-models are told apart, and a merge maps one into the other's frame") {
  TwoSubModels two;
  Reconstruction& r = two.reconstruction;
  CHECK(two.second == Reconstruction::kFirstModelId + 1);
  REQUIRE(two.seen_by_both.size() > 50);
  // Each frame is consistent on its own.
  CHECK(r.MeanReprojectionError() < 1e-9);
  const auto models = r.Models();
  REQUIRE(models.size() == 2);
  CHECK(models[0].first == Reconstruction::kFirstModelId);  // three each: the first registered
  CHECK(models[0].second == std::vector<image_t>{1, 2, 3});
  CHECK(models[1].second == std::vector<image_t>{4, 5, 6});
  for (const auto& [first_id, second_id] : two.seen_by_both) {
    CHECK(r.ModelOfPoint(first_id) == Reconstruction::kFirstModelId);
    CHECK(r.ModelOfPoint(second_id) == two.second);
  }

  // Each apart, as a reader of one model expects it.
  const Reconstruction second = r.SubModel(two.second);
  CHECK(second.RegisteredImageIds() == std::vector<image_t>{4, 5, 6});
  CHECK(second.NumObservations() + r.SubModel(Reconstruction::kFirstModelId).NumObservations() ==
        two.num_observations);
  CHECK(second.MeanReprojectionError() < 1e-9);

  r.TakeChanges();
  r.MergeModels(two.second, Reconstruction::kFirstModelId, Inverse(two.second_from_world));
  const Reconstruction::Changes changes = r.TakeChanges();
  CHECK(changes.changed_images == std::set<image_t>{4, 5, 6});
  CHECK(r.Models().size() == 1);
  CHECK(r.NewModelId() == Reconstruction::kFirstModelId + 1);
  // Back at the truth: the fixture's poses, errors still nil.
  Fixture truth;
  for (const image_t id : {4, 5, 6}) {
    CHECK(r.image(id).model_id == Reconstruction::kFirstModelId);
    CHECK((ProjectionCenter(*r.image(id).cam_from_world) -
           ProjectionCenter(*truth.reconstruction.image(id).cam_from_world))
              .norm() < 1e-9);
  }
  CHECK(r.MeanReprojectionError() < 1e-9);
  // Then the caller fuses the tracks that are one point: every observation
  // kept, one point each.
  const std::size_t num_points = r.NumPoints3D();
  for (const auto& [first_id, second_id] : two.seen_by_both) {
    CHECK((r.point3D(first_id).xyz - r.point3D(second_id).xyz).norm() < 1e-9);
    CHECK(changes.changed_points.count(second_id) == 1);
    CHECK(changes.changed_points.count(first_id) == 0);
    r.MergePoints3D(first_id, second_id);
  }
  CHECK(r.NumPoints3D() == num_points - two.seen_by_both.size());
  CHECK(r.NumObservations() == two.num_observations);
  CHECK(r.MeanReprojectionError() < 1e-9);
}

TEST_CASE("An image keeps its sub-model while it observes points") {
  TwoSubModels two;
  Reconstruction& r = two.reconstruction;
  // Without observations an image may move to another sub-model, and leaves
  // its own when deregistered.
  const image_t id = 4;
  r.DeRegisterImage(id);
  CHECK(r.image(id).model_id == kInvalidModelId);
  r.RegisterImage(id, *Fixture().reconstruction.image(id).cam_from_world);
  CHECK(r.image(id).model_id == Reconstruction::kFirstModelId);
  CHECK(r.Models()[0].second.size() == 4);
}

}  // namespace
}  // namespace flysfm

namespace flysfm {

TEST_CASE("A model written and read back is the same model, a cut or inconsistent one is refused") {
  Fixture f;
  Reconstruction& r = f.reconstruction;
  // An unregistered image and a densified keypoint, as the engine has them.
  const image_t waiting = r.AddImage("waiting.png", r.cameras().begin()->first,
                                     {Eigen::Vector2d(1, 2), Eigen::Vector2d(3, 4)});
  r.AddPoint2D(r.RegisteredImageIds().front(), Eigen::Vector2d(5.5, 6.5));
  // A video frame's rolling-shutter state: capture time, motion, readout.
  Image& frame = r.image(r.RegisteredImageIds().front());
  frame.capture_time = 1305031102.175304;
  frame.angular_velocity = Eigen::Vector3d(0.1, -0.2, 0.3);
  frame.linear_velocity = Eigen::Vector3d(-0.4, 0.5, 0.6);
  r.camera(frame.camera_id).readout_time = 0.025;
  r.UpdatePointErrors();
  std::stringstream stream;
  r.Write(stream);
  const Reconstruction read = Reconstruction::Read(stream);

  CHECK(read.RegisteredImageIds() == r.RegisteredImageIds());
  CHECK_FALSE(read.image(waiting).IsRegistered());
  CHECK(read.NumPoints3D() == r.NumPoints3D());
  CHECK(read.NumObservations() == r.NumObservations());
  CHECK(read.MeanReprojectionError() == r.MeanReprojectionError());
  for (const auto& [id, image] : r.images()) {
    const Image& other = read.image(id);
    CHECK(other.name == image.name);
    CHECK(other.num_points3D == image.num_points3D);
    CHECK(other.capture_time == image.capture_time);
    CHECK(other.angular_velocity == image.angular_velocity);
    CHECK(other.linear_velocity == image.linear_velocity);
    CHECK(read.camera(other.camera_id).readout_time == r.camera(image.camera_id).readout_time);
    REQUIRE(other.points2D.size() == image.points2D.size());
    for (std::size_t i = 0; i < image.points2D.size(); ++i) {
      CHECK(other.points2D[i].xy == image.points2D[i].xy);
      CHECK(other.points2D[i].point3D_id == image.points2D[i].point3D_id);
    }
    if (image.IsRegistered()) {
      CHECK(other.cam_from_world->translation == image.cam_from_world->translation);
      CHECK(other.model_id == image.model_id);
    }
  }
  for (const auto& [id, point] : r.points3D()) {
    CHECK(read.point3D(id).xyz == point.xyz);
    CHECK(read.point3D(id).error == point.error);
    CHECK(read.point3D(id).track.size() == point.track.size());
  }
  // New points get the ids they would have had in the original.
  std::istringstream again(stream.str());
  Reconstruction copy = Reconstruction::Read(again);
  CHECK(copy.AddPoint3D(Eigen::Vector3d::Zero(), {}) == r.AddPoint3D(Eigen::Vector3d::Zero(), {}));

  // Sub-models come back as they were.
  TwoSubModels two;
  std::stringstream two_stream;
  two.reconstruction.Write(two_stream);
  const Reconstruction two_read = Reconstruction::Read(two_stream);
  CHECK(two_read.Models() == two.reconstruction.Models());

  const std::string bytes = stream.str();
  for (const double fraction : {0.0, 0.2, 0.6, 0.999}) {
    std::istringstream cut(bytes.substr(0, std::size_t(fraction * bytes.size())));
    CHECK_THROWS_AS(Reconstruction::Read(cut), std::runtime_error);
  }
}

}  // namespace flysfm
