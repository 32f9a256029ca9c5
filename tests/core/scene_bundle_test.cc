#include "core/scene_bundle.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <random>
#include <set>
#include <unordered_map>
#include <vector>

#include <Eigen/Geometry>
#include <catch2/catch.hpp>

#include "bundle/association_tree.h"
#include "io/evaluation/evaluation.h"
#include "tests/bundle/synthetic_problem.h"
#include "tests/testing/ground_path.h"
#include "tests/testing/scene_model.h"

namespace flysfm {
namespace {

using Tree = HierarchicalAssociationTree;
using testing::SceneImageId;

// A block of three strips; the new image is the last one, its pose perturbed
// as a registration from few correspondences would leave it.
struct LocalScene {
  testing::SyntheticScene scene;
  testing::SceneReconstruction model;
  // Per scene image, the others ranked as retrieval would (scene indices).
  std::vector<std::vector<int>> ranked;
  int new_image = 0;  // scene index
};

LocalScene MakeLocalScene() {
  testing::GroundPathSceneOptions options;
  options.num_images = 120;
  options.images_per_strip = 40;
  options.noise_px = 0.5;
  options.seed = 11;
  LocalScene local;
  local.scene = testing::MakeGroundPathScene(options);
  local.model = testing::ReconstructionFromScene(local.scene);
  local.ranked = testing::RankByCovisibility(local.scene, 8);
  local.new_image = options.num_images - 1;
  Rigid3d pose = local.scene.cams_from_world[local.new_image];
  std::mt19937 rng(12);
  testing::PerturbPose(rng, 1.0, 0.3, &pose);
  local.model.reconstruction.RegisterImage(SceneImageId(local.new_image), pose);
  return local;
}

// The tree's ids are scene image indices; SceneImageWeights maps them to
// image ids.
Tree BuildTree(const LocalScene& local, const Tree::Options& options) {
  return Tree::Build(
      local.new_image, [&](int id) { return local.ranked[id]; }, options);
}

const Rigid3d& PoseOf(const Reconstruction& reconstruction, int scene_image) {
  return *reconstruction.image(SceneImageId(scene_image)).cam_from_world;
}

// The tree's local BA on the model, solved to convergence (the adjuster's
// default options).
SceneBundleResult SolveLocal(const Tree& tree, int max_constant_observers,
                             Reconstruction* reconstruction) {
  return AdjustLocalBundle(testing::SceneImageWeights(tree), BundleAdjuster::Options(),
                           max_constant_observers, reconstruction);
}

// Whether the tree's local BA refines an image (scene index): in the tree,
// with a finite weight.
bool IsRefined(const Tree& tree, int image) {
  const int ripple = tree.RippleOf(image);
  return ripple >= 0 && std::isfinite(tree.options().Weight(ripple));
}

// Per scene point, whether the tree's local block holds it: the model does
// (it is seen twice or more) and a refined image sees it.
std::vector<char> BlockPoints(const LocalScene& local, const Tree& tree) {
  std::vector<char> in_block(local.scene.points.size(), 0);
  for (const testing::SyntheticObservation& obs : local.scene.observations) {
    if (IsRefined(tree, obs.image) && local.model.point_ids[obs.point] != kInvalidPoint3DId) {
      in_block[obs.point] = 1;
    }
  }
  return in_block;
}

// Mean displacement of the camera centres of each ripple, and the largest
// rotation change in it.
struct RippleChange {
  std::vector<double> mean_shift;
  std::vector<double> max_rotation_deg;
};

RippleChange ChangePerRipple(const Tree& tree, const Reconstruction& before,
                             const Reconstruction& after) {
  RippleChange change;
  for (const std::vector<int>& ripple : tree.ripples()) {
    double shift = 0;
    double rotation = 0;
    for (const int id : ripple) {
      const Rigid3d& a = PoseOf(before, id);
      const Rigid3d& b = PoseOf(after, id);
      shift += (ProjectionCenter(a) - ProjectionCenter(b)).norm() / ripple.size();
      rotation = std::max(rotation, RotationDifferenceDeg(a, b));
    }
    change.mean_shift.push_back(shift);
    change.max_rotation_deg.push_back(rotation);
  }
  return change;
}

TEST_CASE("The weighted local BA moves farther ripples less and the last not") {
  const LocalScene local = MakeLocalScene();
  const Reconstruction& before = local.model.reconstruction;
  const Tree tree = BuildTree(local, {});
  REQUIRE(tree.ripples().size() == 4);

  Reconstruction solved = before;
  const BundleAdjuster::Summary summary = SolveLocal(tree, 0, &solved).summary;
  INFO(summary.BriefReport());
  REQUIRE(summary.termination == BundleAdjuster::Termination::kConvergence);
  // Ripple 1 has p = 1, ripple 2 p = k: only ripple 2 gets a prior.
  CHECK(summary.num_pose_priors == static_cast<int>(tree.ripples()[2].size()));

  const RippleChange change = ChangePerRipple(tree, before, solved);
  INFO("shift per ripple " << change.mean_shift[0] << " " << change.mean_shift[1]
                           << " " << change.mean_shift[2] << " "
                           << change.mean_shift[3]);
  CHECK(change.mean_shift[2] < change.mean_shift[1]);
  CHECK(change.mean_shift[3] == 0.0);
  CHECK(change.max_rotation_deg[3] == 0.0);
  // Images outside the tree only lend their observations.
  for (int i = 0; i < static_cast<int>(local.scene.cams_from_world.size()); ++i) {
    if (tree.RippleOf(i) >= 0) continue;
    CHECK(PoseOf(solved, i).translation == PoseOf(before, i).translation);
  }
  // The new image's 1 degree / 0.3 perturbation is undone to a tenth of it.
  // The noise-level error is about 0.01 and 0.05 degree here (0.5 px on 300
  // points at f = 500; a nadir view of nearly flat ground trades tilt for
  // shift at 10 units per radian), an unconverged solve leaves far more.
  const Rigid3d& estimate = PoseOf(solved, local.new_image);
  const Rigid3d& truth = local.scene.cams_from_world[local.new_image];
  CHECK((ProjectionCenter(estimate) - ProjectionCenter(truth)).norm() < 0.03);
  CHECK(RotationDifferenceDeg(estimate, truth) < 0.1);

  SECTION("and ripple 2 moves less than without its weight") {
    Tree::Options plain;
    plain.k = 1;
    plain.fix_outermost_ripple = false;
    Reconstruction unweighted = before;
    REQUIRE(SolveLocal(BuildTree(local, plain), 0, &unweighted)
                .summary.IsSolutionUsable());
    const RippleChange plain_change = ChangePerRipple(tree, before, unweighted);
    CHECK(change.mean_shift[2] < plain_change.mean_shift[2]);
  }
}

TEST_CASE("With k = 1 and no fixed ripple the weighted BA is the plain local BA") {
  const LocalScene local = MakeLocalScene();
  const Reconstruction& before = local.model.reconstruction;
  Tree::Options options;
  options.k = 1;
  options.fix_outermost_ripple = false;
  const Tree tree = BuildTree(local, options);

  // The plain local BA, assembled here independently from the scene: the
  // tree's images free, the points they see, every observation of those
  // points, the other images constant.
  BundleProblem plain = testing::BundleProblemFromScene(local.scene);
  plain.images[local.new_image].cam_from_world = PoseOf(before, local.new_image);
  const std::vector<char> in_block = BlockPoints(local, tree);
  std::vector<BundleObservation> kept;
  for (const BundleObservation& obs : plain.observations) {
    if (in_block[obs.point]) kept.push_back(obs);
  }
  plain.observations = kept;
  for (size_t i = 0; i < plain.images.size(); ++i) {
    plain.images[i].constant_pose = !IsRefined(tree, static_cast<int>(i));
  }
  const BundleAdjuster::Summary plain_summary = BundleAdjuster({}).Solve(&plain);
  REQUIRE(plain_summary.IsSolutionUsable());

  Reconstruction weighted = before;
  const BundleAdjuster::Summary summary = SolveLocal(tree, 0, &weighted).summary;
  REQUIRE(summary.IsSolutionUsable());
  CHECK(summary.num_pose_priors == 0);
  CHECK(summary.num_free_images == plain_summary.num_free_images);
  CHECK(summary.num_residuals == plain_summary.num_residuals);
  CHECK(summary.final_cost == Approx(plain_summary.final_cost).epsilon(1e-9));
  // The same problem in another order: equal up to round-off.
  for (size_t i = 0; i < plain.images.size(); ++i) {
    const Rigid3d& a = plain.images[i].cam_from_world;
    const Rigid3d& b = PoseOf(weighted, static_cast<int>(i));
    CHECK(a.rotation.angularDistance(b.rotation) < 1e-9);
    CHECK((a.translation - b.translation).norm() < 1e-9);
  }
  for (size_t p = 0; p < plain.points.size(); ++p) {
    if (in_block[p]) {
      const point3D_t id = local.model.point_ids[p];
      CHECK((plain.points[p] - weighted.point3D(id).xyz).norm() < 1e-8);
    }
  }
}

TEST_CASE("A local bundle keeps every observation of its points") {
  const LocalScene local = MakeLocalScene();
  const Tree tree = BuildTree(local, {});
  REQUIRE(static_cast<int>(tree.ripples().size()) == tree.options().depth + 1);

  // From the scene: the block's points, their observers and observations,
  // and per point its observations from images held constant (the fixed
  // ripple and images outside the tree).
  const std::vector<char> in_block = BlockPoints(local, tree);
  std::set<point3D_t> block_points;
  for (size_t p = 0; p < in_block.size(); ++p) {
    if (in_block[p]) block_points.insert(local.model.point_ids[p]);
  }
  int num_refined = 0;
  for (int i = 0; i < static_cast<int>(local.scene.cams_from_world.size()); ++i) {
    num_refined += IsRefined(tree, i);
  }
  std::set<int> observers;
  int num_observations = 0;
  int num_refined_observations = 0;
  std::vector<int> num_constant_observations(in_block.size(), 0);
  for (const testing::SyntheticObservation& obs : local.scene.observations) {
    if (!in_block[obs.point]) continue;
    observers.insert(obs.image);
    ++num_observations;
    if (IsRefined(tree, obs.image)) {
      ++num_refined_observations;
    } else {
      ++num_constant_observations[obs.point];
    }
  }
  // Constant observers exist, so counting images tells them apart.
  REQUIRE(static_cast<int>(observers.size()) > num_refined);

  Reconstruction solved = local.model.reconstruction;
  const SceneBundleResult result = SolveLocal(tree, 0, &solved);
  REQUIRE(result.summary.IsSolutionUsable());
  CHECK(std::set<point3D_t>(result.points.begin(), result.points.end()) ==
        block_points);
  CHECK(result.summary.num_points == static_cast<int>(block_points.size()));
  CHECK(result.summary.num_free_images == num_refined);
  CHECK(result.summary.num_images == static_cast<int>(observers.size()));
  CHECK(result.summary.num_residuals == num_observations);

  SECTION("or, capped, every refined one and a few constant ones") {
    constexpr int kCap = 2;
    int expected = num_refined_observations;
    for (const int count : num_constant_observations) expected += std::min(count, kCap);
    // Enough points are seen from more than kCap constant images to tell.
    REQUIRE(expected < num_observations);

    Reconstruction capped = local.model.reconstruction;
    const BundleAdjuster::Summary summary = SolveLocal(tree, kCap, &capped).summary;
    REQUIRE(summary.IsSolutionUsable());
    CHECK(summary.num_free_images == num_refined);
    CHECK(summary.num_residuals == expected);
  }
}

TEST_CASE("A local bundle reports what it moved to the model's change tracking") {
  LocalScene local = MakeLocalScene();
  const Tree tree = BuildTree(local, {});
  Reconstruction& reconstruction = local.model.reconstruction;
  reconstruction.TakeChanges();
  const SceneBundleResult result = SolveLocal(tree, 0, &reconstruction);
  REQUIRE_FALSE(result.points.empty());
  const Reconstruction::Changes changes = reconstruction.TakeChanges();
  // Every point the BA wrote, and only those; every refined image, and no
  // image held constant.
  CHECK(changes.changed_points ==
        std::set<point3D_t>(result.points.begin(), result.points.end()));
  CHECK(changes.added_points.empty());
  CHECK(changes.removed_points.empty());
  // The intrinsics were held constant (the adjuster's default): no change.
  CHECK_FALSE(changes.changed_cameras);
  for (int i = 0; i < static_cast<int>(local.scene.cams_from_world.size()); ++i) {
    CHECK(changes.changed_images.count(SceneImageId(i)) == (IsRefined(tree, i) ? 1u : 0u));
  }
}

TEST_CASE("A local bundle that refines the focal length reports the camera changed") {
  LocalScene local = MakeLocalScene();
  const Tree tree = BuildTree(local, {});
  Reconstruction& reconstruction = local.model.reconstruction;
  // A focal length 1 % off, for the bundle to correct.
  for (auto& [camera_id, camera] : reconstruction.cameras()) {
    reconstruction.camera(camera_id).SetFocalLength(1.01 * camera.MeanFocalLength());
  }
  reconstruction.TakeChanges();
  BundleAdjuster::Options options;
  options.refine_focal_length = true;
  AdjustLocalBundle(testing::SceneImageWeights(tree), options, 0, &reconstruction);
  CHECK(reconstruction.TakeChanges().changed_cameras);
}

// 30 frames of a video, 1/30 s apart, on an arc turning at a steady 1 rad/s
// around the scene, read out in 30 ms: up to about 15 px at the image's top
// and bottom edges. `frame_interval` spaces the capture times.
Reconstruction RollingShutterVideo(double frame_interval) {
  constexpr double kReadout = 0.03;
  testing::SyntheticSceneOptions options;
  options.num_images = 30;
  options.num_points = 1000;
  options.arc_deg = 57.3;
  options.max_tilt_deg = 0;
  options.seed = 21;
  testing::SyntheticScene scene = testing::MakeSyntheticScene(options);
  // Each frame's motion: the exact rates of the steady turn, in its own frame.
  const int n = options.num_images;
  std::mt19937 rng(22);
  std::normal_distribution<double> noise(0, 0.5);
  for (testing::SyntheticObservation& obs : scene.observations) {
    const int before = std::max(obs.image - 1, 0), after = std::min(obs.image + 1, n - 1);
    const Rigid3d motion = scene.cams_from_world[after] * Inverse(scene.cams_from_world[before]);
    const Eigen::AngleAxisd turn(motion.rotation);
    const Eigen::Vector3d angular_velocity = turn.angle() * turn.axis() / ((after - before) / 30.0);
    const Eigen::Vector3d linear_velocity = motion.translation / ((after - before) / 30.0);
    Camera camera = scene.camera;
    camera.readout_time = kReadout;
    const Eigen::Vector3d in_cam = scene.cams_from_world[obs.image] * scene.points[obs.point];
    for (int i = 0; i < 5; ++i) {
      obs.pixel = camera.ImgFromCam(
          camera.InCamAtRow(in_cam, obs.pixel.y(), angular_velocity, linear_velocity));
    }
    obs.pixel += Eigen::Vector2d(noise(rng), noise(rng));
  }
  Reconstruction reconstruction = testing::ReconstructionFromScene(scene).reconstruction;
  for (int i = 0; i < n; ++i) {
    reconstruction.image(SceneImageId(i)).capture_time = 100 + i * frame_interval;
  }
  return reconstruction;
}

TEST_CASE("A global bundle estimates a video's readout time from its frames' motion") {
  Reconstruction video = RollingShutterVideo(1 / 30.0);
  BundleAdjuster::Options options;
  options.refine_readout_time = true;
  const SceneBundleResult result = AdjustGlobalBundle(options, &video);
  INFO(result.summary.BriefReport());
  REQUIRE(result.summary.IsSolutionUsable());
  // Each frame's motion is its neighbours' (a central difference, exact for a
  // steady turn): the readout comes out as rendered, the residuals at the
  // 0.5 px noise (mean norm sigma sqrt(pi / 2)).
  CHECK(video.camera(video.image(SceneImageId(0)).camera_id).readout_time ==
        Approx(0.03).epsilon(0.03));
  CHECK(result.summary.final_mean_reprojection_error_px < 1.1 * 0.5 * std::sqrt(M_PI / 2));

  // The same frames as photos 3 s apart: nothing tells their motion, so the
  // model is a still camera's, and the structure absorbs what it can of the
  // motion (at 0.5 px noise, part of it).
  Reconstruction photos = RollingShutterVideo(3.0);
  const SceneBundleResult still = AdjustGlobalBundle(options, &photos);
  CHECK(photos.camera(photos.image(SceneImageId(0)).camera_id).readout_time == 0);
  CHECK(still.summary.final_mean_reprojection_error_px >
        result.summary.final_mean_reprojection_error_px + 0.01);
}

// Camera-centre RMSE after Sim3 against the scene's true poses.
double CentreRmse(const testing::SyntheticScene& scene, const Reconstruction& reconstruction) {
  std::vector<Eigen::Vector3d> estimated;
  std::vector<Eigen::Vector3d> truth;
  for (int i = 0; i < int(scene.cams_from_world.size()); ++i) {
    estimated.push_back(ProjectionCenter(PoseOf(reconstruction, i)));
    truth.push_back(ProjectionCenter(scene.cams_from_world[i]));
  }
  const std::optional<PositionErrors> errors = ComparePositionsAfterSim3(estimated, truth);
  REQUIRE(errors);
  return errors->rmse;
}

// Observations of two precisions, as LSM leaves them: most sharpened at full
// resolution (0.15 px), a quarter where only a coarse level held (0.6 px),
// and 2 % of blunders of 2.5 - 3.5 px, under the engine's 4 px filter.
struct MixedPrecisionScene {
  testing::SyntheticScene scene;
  Reconstruction truth;
  Reconstruction noisy;
  std::set<std::pair<image_t, point2D_t>> precise;
  std::set<std::pair<image_t, point2D_t>> blunders;
};

MixedPrecisionScene MakeMixedPrecisionScene(std::uint32_t seed) {
  testing::GroundPathSceneOptions scene_options;
  scene_options.num_images = 40;
  scene_options.images_per_strip = 20;
  scene_options.seed = seed;
  MixedPrecisionScene mixed;
  mixed.scene = testing::MakeGroundPathScene(scene_options);
  mixed.truth = testing::ReconstructionFromScene(mixed.scene).reconstruction;
  mixed.noisy = mixed.truth;
  std::mt19937 rng(seed + 1);
  std::uniform_real_distribution<double> unit(0, 1);
  std::normal_distribution<double> normal(0, 1);
  for (const auto& [id, point] : mixed.truth.points3D()) {
    for (const TrackElement& element : point.track) {
      Eigen::Vector2d& xy = mixed.noisy.image(element.image_id).points2D[element.point2D_idx].xy;
      const double kind = unit(rng);
      if (kind < 0.02) {
        const double angle = 2 * M_PI * unit(rng);
        xy += (2.5 + unit(rng)) * Eigen::Vector2d(std::cos(angle), std::sin(angle));
        mixed.blunders.insert({element.image_id, element.point2D_idx});
      } else {
        const double sigma = kind < 0.27 ? 0.6 : 0.15;
        xy += sigma * Eigen::Vector2d(normal(rng), normal(rng));
        if (sigma < 0.5) mixed.precise.insert({element.image_id, element.point2D_idx});
      }
    }
  }
  return mixed;
}

// All observations enter the BA with one weight; the snooping keeps those
// measured at each image's own precision. A scene's centre error is one
// sample of a spread about what least squares predicts (ratios of 0.68 to
// 0.94 below, over scenes): the figures are checked over eight scenes.
TEST_CASE("Snooping keeps the observations measured at each image's precision") {
  const BundleAdjuster::Options options;
  std::size_t blunders = 0, blunders_kept = 0, precise = 0, precise_kept = 0;
  double all_over_oracle = 0, snooped_over_all = 0;
  const int num_scenes = 8;
  for (int seed = 5; seed < 5 + num_scenes; ++seed) {
    const MixedPrecisionScene mixed = MakeMixedPrecisionScene(std::uint32_t(seed));
    // What the snooping aims at: a BA that knew which observations were precise.
    Reconstruction oracle = mixed.noisy;
    for (const auto& [id, point] : mixed.truth.points3D()) {
      for (const TrackElement& element : point.track) {
        if (!mixed.precise.count({element.image_id, element.point2D_idx}) &&
            oracle.image(element.image_id).points2D[element.point2D_idx].HasPoint3D()) {
          oracle.DeleteObservation(element.image_id, element.point2D_idx);
        }
      }
    }
    Reconstruction all = mixed.noisy;
    REQUIRE(AdjustGlobalBundle(options, &oracle).summary.IsSolutionUsable());
    REQUIRE(AdjustGlobalBundle(options, &all).summary.IsSolutionUsable());
    Reconstruction snooped = all;
    const OutlierSnooping snooping = SnoopOutliers(0.99, 10, options, 0, &snooped);
    REQUIRE(snooping.summary.IsSolutionUsable());
    CHECK(snooping.max_error_px.size() == 40);
    blunders += mixed.blunders.size();
    for (const auto& [image_id, point2D_idx] : mixed.blunders) {
      blunders_kept += snooped.image(image_id).points2D[point2D_idx].HasPoint3D();
    }
    precise += mixed.precise.size();
    for (const auto& [image_id, point2D_idx] : mixed.precise) {
      precise_kept += snooped.image(image_id).points2D[point2D_idx].HasPoint3D();
    }
    const double all_rmse = CentreRmse(mixed.scene, all);
    all_over_oracle += all_rmse / CentreRmse(mixed.scene, oracle) / num_scenes;
    snooped_over_all += CentreRmse(mixed.scene, snooped) / all_rmse / num_scenes;
  }
  // A blunder along a two-view track's epipolar line moves the point, not
  // the error: nothing can show it.
  INFO(blunders_kept << " of " << blunders << " blunders kept");
  CHECK(double(blunders_kept) <= 0.03 * double(blunders));
  // Within a precision, the 0.99 quantile: about 1 % of the precise go (the
  // median, pulled up a little by the coarse ones, loosens the bound).
  CHECK(double(precise_kept) >= 0.97 * double(precise));
  INFO("centre RMSE, mean ratios: all / oracle " << all_over_oracle << ", snooped / all "
                                                 << snooped_over_all);
  // Least squares with one weight has a variance of mean(sigma^2) / n: all
  // observations (0.75 0.15^2 + 0.25 0.6^2) / n, 1.9 times the oracle's
  // error; kept within 2.58 x the median (about 0.49 px), 28 % of the coarse
  // ones remain, 1.45 times the oracle's error: 0.76 times all's.
  CHECK(all_over_oracle >= 1.5);
  CHECK(snooped_over_all <= 0.85);
}

// The cost another global BA still takes off a snooped model, relative: at
// the optimum of what it holds, no more than the solver's own stopping rule
// leaves (an iteration gaining under function_tolerance ends it; ten such).
double CostLeft(const Reconstruction& snooped, const BundleAdjuster::Options& options) {
  Reconstruction again = snooped;
  const BundleAdjuster::Summary summary = AdjustGlobalBundle(options, &again).summary;
  REQUIRE(summary.IsSolutionUsable());
  return (summary.initial_cost - summary.final_cost) / summary.initial_cost;
}

TEST_CASE("Snooping ends at the optimum of what it keeps, with nothing beyond its bound") {
  MixedPrecisionScene mixed = MakeMixedPrecisionScene(5);
  const BundleAdjuster::Options options;
  REQUIRE(AdjustGlobalBundle(options, &mixed.noisy).summary.IsSolutionUsable());
  Reconstruction snooped = mixed.noisy;
  const OutlierSnooping snooping = SnoopOutliers(0.99, 10, options, 0, &snooped);
  REQUIRE(snooping.summary.IsSolutionUsable());
  // The first adjustment without the dropped observations moves the errors
  // of others past their bound: one round is not enough, and a few are.
  CHECK(snooping.num_rounds >= 2);
  CHECK(snooping.num_rounds < 10);
  std::size_t beyond = 0;
  for (const auto& [id, point] : snooped.points3D()) {
    for (const TrackElement& element : point.track) {
      beyond += snooped.ReprojectionError(element.image_id, element.point2D_idx, point.xyz) >
                snooping.max_error_px.at(element.image_id);
    }
  }
  CHECK(beyond == 0);
  const double tolerance = 10 * options.function_tolerance;
  CHECK(CostLeft(snooped, options) <= tolerance);
  // Stopped after its first adjustment, the model still had cost to lose.
  Reconstruction once = mixed.noisy;
  REQUIRE(SnoopOutliers(0.99, 1, options, 0, &once).num_rounds == 1);
  CHECK(CostLeft(once, options) > tolerance);
}

// Between shots a large model's refinement adjusts the images registered
// last; its snooping judges those images' observations and moves only them
// and their points.
TEST_CASE("Snooping over some images judges and moves those alone") {
  MixedPrecisionScene mixed = MakeMixedPrecisionScene(6);
  const BundleAdjuster::Options options;
  REQUIRE(AdjustGlobalBundle(options, &mixed.noisy).summary.IsSolutionUsable());
  std::unordered_map<image_t, double> weights;
  for (int i = 30; i < 40; ++i) weights[SceneImageId(i)] = 1.0;
  // Held: observes the block's points, is not judged.
  weights[SceneImageId(29)] = std::numeric_limits<double>::infinity();
  Reconstruction snooped = mixed.noisy;
  const OutlierSnooping snooping = SnoopOutliers(weights, 0, 0.99, 10, options, 0, &snooped);
  REQUIRE(snooping.summary.IsSolutionUsable());
  CHECK(snooping.num_removed > 0);
  CHECK(snooping.num_rounds < 10);
  CHECK(snooping.max_error_px.size() == 10);
  CHECK(snooping.max_error_px.count(SceneImageId(29)) == 0);
  std::size_t beyond = 0, lost_elsewhere = 0;
  for (int i = 0; i < 40; ++i) {
    const image_t id = SceneImageId(i);
    const Image& before = mixed.noisy.image(id);
    const Image& after = snooped.image(id);
    const auto bound = snooping.max_error_px.find(id);
    if (bound == snooping.max_error_px.end()) {
      // Not judged: unmoved, and an observation goes only with its whole
      // point, a track that a drop elsewhere left with one element.
      CHECK(after.cam_from_world->rotation.coeffs() == before.cam_from_world->rotation.coeffs());
      CHECK(after.cam_from_world->translation == before.cam_from_world->translation);
      for (std::size_t idx = 0; idx < before.points2D.size(); ++idx) {
        const point3D_t point = before.points2D[idx].point3D_id;
        lost_elsewhere += point != kInvalidPoint3DId && !after.points2D[idx].HasPoint3D() &&
                          snooped.ExistsPoint3D(point);
      }
      continue;
    }
    for (point2D_t idx = 0; idx < after.points2D.size(); ++idx) {
      if (!after.points2D[idx].HasPoint3D()) continue;
      beyond += snooped.ReprojectionError(
                    id, idx, snooped.point3D(after.points2D[idx].point3D_id).xyz) >
                bound->second;
    }
  }
  CHECK(beyond == 0);
  CHECK(lost_elsewhere == 0);
}

}  // namespace
}  // namespace flysfm
