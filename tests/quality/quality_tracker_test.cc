#include "quality/quality_tracker.h"

#include <cmath>
#include <limits>
#include <map>
#include <set>

#include <catch2/catch.hpp>

#include "tests/testing/scene_reconstruction.h"

namespace flysfm {
namespace {

Reconstruction Scene(double noise_px = 0.5) {
  testing::SyntheticSceneOptions options;
  options.num_images = 6;
  options.num_points = 200;
  options.noise_px = noise_px;
  options.seed = 7;
  return testing::ReconstructionFromScene(testing::MakeSyntheticScene(options)).reconstruction;
}

bool SameSigma(const std::optional<double>& a, const std::optional<double>& b,
               double relative = 1e-9) {
  if (!a || !b) return !a && !b;
  return *a == Approx(*b).epsilon(relative);
}

// A fixed pixel noise: the incremental cases compare with MeasurePoint and
// MeasureImage at that noise.
QualityTracker::Options Fixed() {
  QualityTracker::Options options;
  options.sigma_source = QualityTracker::Options::Sigma::kFixed;
  return options;
}

// Every measure of `tracker` (a fixed or model-wide noise) equals a
// measurement of the model from scratch;
// the images' centre sigmas within `center_relative` (relative).
void CheckCurrent(const QualityTracker& tracker, const Reconstruction& r,
                  double center_relative = 1e-9) {
  const double sigma = tracker.SigmaPx();
  REQUIRE(tracker.Points().size() == r.NumPoints3D());
  for (const auto& [id, point] : r.points3D()) {
    const PointQuality expected = MeasurePoint(r, id, sigma);
    const std::optional<PointQuality> tracked = tracker.Point(id);
    REQUIRE(tracked);
    CHECK(tracked->views == expected.views);
    CHECK(tracked->max_angle_deg == expected.max_angle_deg);
    CHECK(tracked->error_px == expected.error_px);
    CHECK(SameSigma(tracked->sigma, expected.sigma));
  }
  REQUIRE(tracker.Images().size() == r.NumRegisteredImages());
  for (const image_t id : r.RegisteredImageIds()) {
    const ImageQuality expected = MeasureImage(r, id, sigma);
    const std::optional<ImageQuality> tracked = tracker.Image(id);
    REQUIRE(tracked);
    CHECK(tracked->inliers == expected.inliers);
    CHECK(tracked->spread == expected.spread);
    CHECK(SameSigma(tracked->center_sigma, expected.center_sigma, center_relative));
  }
}

TEST_CASE("A rebuilt tracker holds every point's and image's measures") {
  const Reconstruction r = Scene();
  QualityTracker tracker(Fixed());
  tracker.Rebuild(r);
  CheckCurrent(tracker, r);
  const QualityTracker::Summary summary = tracker.Summarize();
  CHECK(summary.points == r.NumPoints3D());
  CHECK(summary.images == r.NumRegisteredImages());
  CHECK(summary.last_recomputed_points == r.NumPoints3D());
  CHECK(summary.sigma_px == 1.0);
  std::size_t well_covered = 0;
  for (const auto& [id, point] : r.points3D()) {
    well_covered += point.track.size() >= 3 && r.TriangulationAngleDeg(id) >= 10;
  }
  CHECK(summary.well_covered_points == well_covered);
  CHECK(summary.well_covered_share == Approx(double(well_covered) / r.NumPoints3D()));
}

TEST_CASE("An update recomputes only what the change touched, and agrees with a rebuild") {
  Reconstruction r = Scene();
  QualityTracker tracker(Fixed());
  r.TakeChanges();
  tracker.Rebuild(r);
  std::vector<point3D_t> ids;
  for (const auto& [id, point] : r.points3D()) ids.push_back(id);
  std::sort(ids.begin(), ids.end());

  SECTION("a point moved: itself; the images observing it keep their measures") {
    const point3D_t moved = ids[0];
    const Eigen::Vector3d step(0.01, -0.02, 0.03);
    r.point3D(moved).xyz += step;
    r.MarkPointChanged(moved);
    tracker.Update(r, r.TakeChanges());
    const QualityTracker::Summary summary = tracker.Summarize();
    CHECK(summary.last_recomputed_points == 1);
    CHECK(summary.last_recomputed_images == 0);
    // What they kept is off by what one of their rays turned, at most the
    // step over the point's depth (twice: direction and range).
    double nearest = std::numeric_limits<double>::infinity();
    for (const TrackElement& element : r.point3D(moved).track) {
      const Eigen::Vector3d in_cam = *r.image(element.image_id).cam_from_world * r.point3D(moved).xyz;
      nearest = std::min(nearest, in_cam.z());
    }
    CheckCurrent(tracker, r, 2 * step.norm() / nearest);
  }
  SECTION("an image moved: itself and the points it observes") {
    const image_t image_id = r.RegisteredImageIds()[2];
    Rigid3d pose = *r.image(image_id).cam_from_world;
    pose.translation += Eigen::Vector3d(0.02, 0, 0);
    r.RegisterImage(image_id, pose);
    tracker.Update(r, r.TakeChanges());
    const QualityTracker::Summary summary = tracker.Summarize();
    CHECK(summary.last_recomputed_images == 1);
    CHECK(summary.last_recomputed_points == std::size_t(r.image(image_id).num_points3D));
    CheckCurrent(tracker, r);
  }
  SECTION("a point removed: the images that observed it, and it is gone") {
    const point3D_t gone = ids[1];
    const std::size_t track = r.point3D(gone).track.size();
    r.DeletePoint3D(gone);
    tracker.Update(r, r.TakeChanges());
    const QualityTracker::Summary summary = tracker.Summarize();
    CHECK(summary.last_recomputed_points == 0);
    CHECK(summary.last_recomputed_images == track);
    CHECK_FALSE(tracker.Point(gone));
    CheckCurrent(tracker, r);
  }
  SECTION("an observation dropped: its point and the image that lost it") {
    const point3D_t thinned = ids[2];
    const std::vector<TrackElement> track = r.point3D(thinned).track;
    REQUIRE(track.size() >= 3);
    r.DeleteObservation(track[0].image_id, track[0].point2D_idx);
    tracker.Update(r, r.TakeChanges());
    const QualityTracker::Summary summary = tracker.Summarize();
    CHECK(summary.last_recomputed_points == 1);
    // The point did not move: the rest of its track sees what it saw.
    CHECK(summary.last_recomputed_images == 1);
    CheckCurrent(tracker, r);
  }
  SECTION("an image deregistered: it leaves, its points are measured without it") {
    const image_t image_id = r.RegisteredImageIds()[0];
    r.DeRegisterImage(image_id);
    tracker.Update(r, r.TakeChanges());
    CHECK_FALSE(tracker.Image(image_id));
    CheckCurrent(tracker, r);
  }
  SECTION("intrinsics written: everything") {
    r.camera(r.cameras().begin()->first).params[0] *= 1.01;
    r.MarkCamerasChanged();
    tracker.Update(r, r.TakeChanges());
    const QualityTracker::Summary summary = tracker.Summarize();
    CHECK(summary.last_recomputed_points == r.NumPoints3D());
    CHECK(summary.last_recomputed_images == r.NumRegisteredImages());
    CheckCurrent(tracker, r);
  }
  SECTION("nothing changed: nothing recomputed") {
    tracker.Update(r, r.TakeChanges());
    CHECK(tracker.Summarize().last_recomputed_points == 0);
    CHECK(tracker.Summarize().last_recomputed_images == 0);
  }
  CHECK(tracker.Summarize().updates == 2);
}

// A tracker with a fixed noise and no refresh budget, measuring `r`.
QualityTracker WithoutBudget(Reconstruction* r) {
  QualityTracker::Options options = Fixed();
  options.refresh_budget_ms = 0;
  QualityTracker tracker(options);
  r->TakeChanges();
  tracker.Rebuild(*r);
  return tracker;
}

TEST_CASE("Past the refresh budget what a bundle only moved waits, and new points never wait") {
  Reconstruction r = Scene();
  QualityTracker tracker = WithoutBudget(&r);

  // A pose and a point moved, as a local BA moves them.
  const image_t image_id = r.RegisteredImageIds()[2];
  Rigid3d pose = *r.image(image_id).cam_from_world;
  pose.translation += Eigen::Vector3d(0.02, 0, 0);
  r.RegisterImage(image_id, pose);
  const point3D_t moved = r.points3D().begin()->first;
  bool moved_seen_by_image = false;
  for (const TrackElement& element : r.point3D(moved).track) {
    moved_seen_by_image |= element.image_id == image_id;
  }
  const Eigen::Vector3d step(0.01, -0.02, 0.03);
  r.point3D(moved).xyz += step;
  r.MarkPointChanged(moved);
  double nearest = std::numeric_limits<double>::infinity();
  for (const TrackElement& element : r.point3D(moved).track) {
    nearest = std::min(nearest, (*r.image(element.image_id).cam_from_world * r.point3D(moved).xyz).z());
  }
  tracker.Update(r, r.TakeChanges());
  const QualityTracker::Summary waiting = tracker.Summarize();
  CHECK(waiting.last_recomputed_points == 0);
  CHECK(waiting.last_recomputed_images == 0);
  CHECK(waiting.deferred_images == 1);
  CHECK(waiting.deferred_points ==
        std::size_t(r.image(image_id).num_points3D) + (moved_seen_by_image ? 0 : 1));
  CHECK(tracker.Point(moved)->sigma != MeasurePoint(r, moved, 1.0).sigma);

  // A point triangulated again: the old one goes, the new one is measured at
  // once; the images that observed the old one wait, their observations
  // changed (a thousand each in a real model).
  point3D_t old_point = moved;
  for (const auto& [id, point] : r.points3D()) {
    if (id != moved) old_point = id;
  }
  REQUIRE(old_point != moved);
  const Eigen::Vector3d old_xyz = r.point3D(old_point).xyz;
  const std::vector<TrackElement> track = r.point3D(old_point).track;
  r.DeletePoint3D(old_point);
  const point3D_t added = r.AddPoint3D(old_xyz, track);
  tracker.Update(r, r.TakeChanges());
  CHECK_FALSE(tracker.Point(old_point));
  CHECK(tracker.Point(added)->views == int(track.size()));
  CHECK(tracker.Point(added)->sigma == MeasurePoint(r, added, 1.0).sigma);
  CHECK(tracker.Summarize().last_recomputed_images == 0);
  std::set<image_t> waiting_images = {image_id};
  for (const TrackElement& element : track) waiting_images.insert(element.image_id);
  CHECK(tracker.Summarize().deferred_images == waiting_images.size());

  // Flush: everything current, nothing waits.
  tracker.Flush(r);
  CHECK(tracker.Summarize().deferred_points == 0);
  CHECK(tracker.Summarize().deferred_images == 0);
  // The images seeing the moved point keep their measures (above).
  CheckCurrent(tracker, r, 2 * step.norm() / nearest);
  CHECK(SameSigma(tracker.Image(image_id)->center_sigma,
                  MeasureImage(r, image_id, 1.0).center_sigma));
}

TEST_CASE("A track that only grew is measured at the cost of what it gained, as from scratch") {
  Reconstruction r = Scene();
  QualityTracker tracker = WithoutBudget(&r);
  point3D_t id = kInvalidPoint3DId;
  for (const auto& [candidate, point] : r.points3D()) {
    if (point.track.size() >= 3) id = candidate;
  }
  REQUIRE(id != kInvalidPoint3DId);
  // Its last observation dropped (measured again), then given back: the
  // track grew by one, as a new image's match extends it.
  const TrackElement last = r.point3D(id).track.back();
  r.DeleteObservation(last.image_id, last.point2D_idx);
  tracker.Update(r, r.TakeChanges());
  r.AddObservation(id, last);
  tracker.Update(r, r.TakeChanges());
  CHECK(tracker.Summarize().last_recomputed_points == 1);
  // The exact measure is still queued (the point may have moved as it grew).
  CHECK(tracker.Summarize().deferred_points == 1);
  // It did not move here: the extended measure is the measure from scratch.
  const PointQuality expected = MeasurePoint(r, id, 1.0);
  const PointQuality extended = *tracker.Point(id);
  CHECK(extended.views == expected.views);
  CHECK(extended.max_angle_deg == Approx(expected.max_angle_deg).epsilon(1e-12));
  CHECK(extended.error_px == Approx(expected.error_px).epsilon(1e-12));
  CHECK(extended.squared_error_sum == Approx(expected.squared_error_sum).epsilon(1e-12));
  CHECK(SameSigma(extended.sigma, expected.sigma));
}

TEST_CASE("With the model's RMS as the pixel noise, every sigma scales with it") {
  const Reconstruction r = Scene(0.8);
  QualityTracker::Options options;
  options.sigma_source = QualityTracker::Options::Sigma::kModelRms;
  QualityTracker by_rms(options);
  QualityTracker by_pixel(Fixed());
  by_rms.Rebuild(r);
  by_pixel.Rebuild(r);
  double squared = 0;
  std::size_t count = 0;
  for (const auto& [id, point] : r.points3D()) {
    for (const TrackElement& element : point.track) {
      squared += std::pow(r.ReprojectionError(element.image_id, element.point2D_idx, point.xyz), 2);
      ++count;
    }
  }
  const double rms = std::sqrt(squared / count);
  CHECK(by_rms.SigmaPx() == Approx(rms).epsilon(1e-12));
  CHECK(by_rms.Summarize().sigma_px == Approx(rms).epsilon(1e-12));
  const point3D_t id = r.points3D().begin()->first;
  CHECK(*by_rms.Point(id)->sigma == Approx(rms * *by_pixel.Point(id)->sigma).epsilon(1e-12));
  const image_t image_id = r.RegisteredImageIds().front();
  CHECK(*by_rms.Image(image_id)->center_sigma ==
        Approx(rms * *by_pixel.Image(image_id)->center_sigma).epsilon(1e-12));
  CheckCurrent(by_rms, r);
}

TEST_CASE("A posteriori, each point and image is judged by its own residuals, the model's "
          "noise as a prior") {
  // Keypoints with 0.5 px of noise per coordinate about exact points.
  const double noise_px = 0.5;
  const Reconstruction r = Scene(noise_px);
  QualityTracker::Options options;
  options.sigma_source = QualityTracker::Options::Sigma::kAPosteriori;
  QualityTracker tracker(options);
  tracker.Rebuild(r);
  QualityTracker by_pixel(Fixed());
  by_pixel.Rebuild(r);

  double squared = 0;
  std::size_t count = 0;
  std::map<image_t, std::pair<double, int>> per_image;  // squared sum, points
  std::map<point3D_t, double> per_point;
  for (const auto& [id, point] : r.points3D()) {
    for (const TrackElement& element : point.track) {
      const double e2 = std::pow(r.ReprojectionError(element.image_id, element.point2D_idx,
                                                     point.xyz), 2);
      squared += e2;
      ++count;
      per_point[id] += e2;
      per_image[element.image_id].first += e2;
      ++per_image[element.image_id].second;
    }
  }
  // The model's noise per coordinate: the keypoints' own, to the statistical
  // error of about a thousand residuals (a few per cent).
  const double model_sigma = std::sqrt(squared / (2.0 * double(count)));
  CHECK(tracker.SigmaPx() == Approx(model_sigma).epsilon(1e-12));
  CHECK(tracker.SigmaPx() == Approx(noise_px).epsilon(0.1));

  const double prior = options.prior_redundancy;
  for (const auto& [id, point] : r.points3D()) {
    const double redundancy = 2.0 * double(point.track.size()) - 3.0;
    const double own = std::sqrt((per_point[id] + prior * model_sigma * model_sigma) /
                                 (redundancy + prior));
    CHECK(*tracker.Point(id)->sigma == Approx(own * *by_pixel.Point(id)->sigma).epsilon(1e-9));
  }
  for (const auto& [image_id, sums] : per_image) {
    const double redundancy = 2.0 * sums.second - 6.0;
    const double own = std::sqrt((sums.first + prior * model_sigma * model_sigma) /
                                 (redundancy + prior));
    CHECK(*tracker.Image(image_id)->center_sigma ==
          Approx(own * *by_pixel.Image(image_id)->center_sigma).epsilon(1e-9));
  }

  // A model without residuals: every point is as certain as its geometry
  // with no noise at all, and the prior keeps that from being a division by
  // zero.
  const Reconstruction exact = Scene(0.0);
  QualityTracker exact_tracker(options);
  exact_tracker.Rebuild(exact);
  for (const auto& [id, point] : exact.points3D()) {
    if (const auto sigma = exact_tracker.Point(id)->sigma) CHECK(*sigma == Approx(0).margin(1e-9));
  }
}

TEST_CASE("Sigma sources are named as summary.json names them, and read back") {
  using Sigma = QualityTracker::Options::Sigma;
  for (const Sigma source : {Sigma::kFixed, Sigma::kModelRms, Sigma::kAPosteriori}) {
    CHECK(SigmaSourceFromName(SigmaSourceName(source)) == source);
  }
  CHECK(std::string(SigmaSourceName(Sigma::kAPosteriori)) == "a-posteriori");
  CHECK_FALSE(SigmaSourceFromName("magic"));
}

TEST_CASE("Bad quality options are refused, naming the option") {
  QualityTracker::Options options;
  options.sigma_px = 0;
  CHECK_THROWS_WITH(QualityTracker(options), Catch::Contains("sigma_px"));
  options = {};
  options.min_views = 1;
  CHECK_THROWS_WITH(QualityTracker(options), Catch::Contains("min_views"));
  options = {};
  options.refresh_budget_ms = -1;
  CHECK_THROWS_WITH(QualityTracker(options), Catch::Contains("refresh_budget_ms"));
  options = {};
  options.prior_redundancy = 0;
  CHECK_THROWS_WITH(QualityTracker(options), Catch::Contains("prior_redundancy"));
  options = {};
  options.min_angle_deg = -1;
  CHECK_THROWS_WITH(QualityTracker(options), Catch::Contains("min_angle_deg"));
}

}  // namespace
}  // namespace flysfm
