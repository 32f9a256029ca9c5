#include "bundle/bundle_adjuster.h"

#include <algorithm>
#include <cmath>
#include <memory>
#include <random>
#include <tuple>
#include <utility>
#include <vector>

// Ceres pulls in glog, whose CHECK would silently replace Catch's: include it
// first and drop glog's macro before Catch defines its own.
#include <ceres/ceres.h>
#undef CHECK
#include <catch2/catch.hpp>

#include "bundle/cost_functions.h"
#include "tests/bundle/synthetic_problem.h"
#include "tests/testing/synthetic.h"

namespace flysfm {
namespace {

using testing::BundleProblemFromScene;
using testing::PerturbPose;
using testing::RmsReprojectionError;

constexpr double kNoisePx = 0.5;

// The reference scene: 30 cameras on an arc around 2 000 points.
testing::SyntheticScene ArcScene(double noise_px, std::uint32_t seed,
                                 const Camera& camera = Camera::FromFocal(
                                     CameraModelId::kPinhole, 500, 640, 480)) {
  testing::SyntheticSceneOptions options;
  options.num_images = 30;
  options.num_points = 2000;
  options.noise_px = noise_px;
  options.camera = camera;
  options.seed = seed;
  return testing::MakeSyntheticScene(options);
}

// Starting point of a solve: every pose from `first_free` on rotated by 1
// degree and moved by 0.1 (the scene is 2 across, 5 away), every point moved
// by up to 0.05 per axis.
void Perturb(std::uint32_t seed, int first_free, BundleProblem* problem) {
  std::mt19937 rng(seed);
  for (size_t i = first_free; i < problem->images.size(); ++i) {
    PerturbPose(rng, 1.0, 0.1, &problem->images[i].cam_from_world);
  }
  std::uniform_real_distribution<double> shift(-0.05, 0.05);
  for (Eigen::Vector3d& point : problem->points) {
    point += Eigen::Vector3d(shift(rng), shift(rng), shift(rng));
  }
}

struct PoseErrors {
  double rotation_rms_rad = 0;
  double translation_rms = 0;
};

PoseErrors ComparePoses(const BundleProblem& problem,
                        const testing::SyntheticScene& scene, int first) {
  PoseErrors errors;
  const int n = static_cast<int>(scene.cams_from_world.size()) - first;
  for (size_t i = first; i < scene.cams_from_world.size(); ++i) {
    const Rigid3d& estimate = problem.images[i].cam_from_world;
    const Rigid3d& truth = scene.cams_from_world[i];
    const double angle = estimate.rotation.angularDistance(truth.rotation);
    errors.rotation_rms_rad += angle * angle / n;
    errors.translation_rms +=
        (estimate.translation - truth.translation).squaredNorm() / n;
  }
  errors.rotation_rms_rad = std::sqrt(errors.rotation_rms_rad);
  errors.translation_rms = std::sqrt(errors.translation_rms);
  return errors;
}

// The Cramér-Rao bound of the poses from `first` on, with the poses before it
// held: the RMS errors an efficient estimator reaches under pixel noise of
// `sigma` per axis, from the inverse Fisher information sigma^2 (J^T J)^-1 at
// the ground truth. Rotation errors are angles: twice the tangent of
// ceres::EigenQuaternionManifold.
PoseErrors CramerRaoBound(const testing::SyntheticScene& scene, int first,
                          double sigma) {
  BundleProblem truth = BundleProblemFromScene(scene);
  ceres::Problem::Options problem_options;
  problem_options.manifold_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  ceres::Problem problem(problem_options);
  ceres::EigenQuaternionManifold quaternion_manifold;
  double* params = truth.cameras[0].params.data();
  for (const BundleObservation& obs : truth.observations) {
    Rigid3d& pose = truth.images[obs.image].cam_from_world;
    double* point = truth.points[obs.point].data();
    if (obs.image < first) {
      problem.AddResidualBlock(CreateConstantPoseReprojectionCost(
                                   scene.camera.model_id, pose, obs.pixel),
                               nullptr, point, params);
    } else {
      problem.AddResidualBlock(
          CreateReprojectionCost(scene.camera.model_id, obs.pixel), nullptr,
          pose.rotation.coeffs().data(), pose.translation.data(), point, params);
      problem.SetManifold(pose.rotation.coeffs().data(), &quaternion_manifold);
    }
  }
  problem.SetParameterBlockConstant(params);

  ceres::Covariance::Options options;
  options.algorithm_type = ceres::SPARSE_QR;
  ceres::Covariance covariance(options);
  std::vector<std::pair<const double*, const double*>> blocks;
  for (size_t i = first; i < truth.images.size(); ++i) {
    const Rigid3d& pose = truth.images[i].cam_from_world;
    blocks.emplace_back(pose.rotation.coeffs().data(), pose.rotation.coeffs().data());
    blocks.emplace_back(pose.translation.data(), pose.translation.data());
  }
  REQUIRE(covariance.Compute(blocks, &problem));

  PoseErrors bound;
  const int n = static_cast<int>(truth.images.size()) - first;
  for (size_t i = first; i < truth.images.size(); ++i) {
    const Rigid3d& pose = truth.images[i].cam_from_world;
    Eigen::Matrix3d rotation, translation;
    covariance.GetCovarianceBlockInTangentSpace(pose.rotation.coeffs().data(),
                                               pose.rotation.coeffs().data(),
                                               rotation.data());
    covariance.GetCovarianceBlock(pose.translation.data(), pose.translation.data(),
                                  translation.data());
    bound.rotation_rms_rad += 4 * rotation.trace() / n;
    bound.translation_rms += translation.trace() / n;
  }
  bound.rotation_rms_rad = sigma * std::sqrt(bound.rotation_rms_rad);
  bound.translation_rms = sigma * std::sqrt(bound.translation_rms);
  return bound;
}

// Images 0 and 1 stay at the truth and hold the gauge, so the other poses are
// compared with the truth directly.
BundleProblem PerturbedArcProblem(const testing::SyntheticScene& scene) {
  BundleProblem problem = BundleProblemFromScene(scene);
  problem.images[0].constant_pose = true;
  problem.images[1].constant_pose = true;
  Perturb(17, 2, &problem);
  return problem;
}

TEST_CASE("Global BA reaches the noise floor and the Cramer-Rao pose accuracy") {
  const testing::SyntheticScene scene = ArcScene(kNoisePx, 1);
  BundleProblem problem = PerturbedArcProblem(scene);
  REQUIRE(RmsReprojectionError(problem) > 10 * kNoisePx);

  const BundleAdjuster::Summary summary = BundleAdjuster({}).Solve(&problem);
  INFO(summary.BriefReport());
  REQUIRE(summary.termination == BundleAdjuster::Termination::kConvergence);
  CHECK(summary.num_free_images == 28);
  CHECK(summary.final_cost < summary.initial_cost);
  // Residual RMS per axis tends to the noise sigma (less the ~5 % of degrees
  // of freedom the fit absorbs).
  CHECK(std::abs(RmsReprojectionError(problem) - kNoisePx) < 0.1 * kNoisePx);
  // Mean of a 2D Gaussian residual's norm: sigma sqrt(pi/2).
  CHECK(summary.final_mean_reprojection_error_px ==
        Approx(kNoisePx * std::sqrt(M_PI / 2)).epsilon(0.1));

  // RMS over 28 poses of an efficient estimate is within a few percent of the
  // bound; twice the bound leaves room for the Huber loss' small loss of
  // efficiency, and a solver stopping short would miss it by far.
  const PoseErrors errors = ComparePoses(problem, scene, 2);
  const PoseErrors bound = CramerRaoBound(scene, 2, kNoisePx);
  INFO("rotation " << errors.rotation_rms_rad << " rad, bound "
                   << bound.rotation_rms_rad << "; translation "
                   << errors.translation_rms << ", bound " << bound.translation_rms);
  CHECK(errors.rotation_rms_rad < 2 * bound.rotation_rms_rad);
  CHECK(errors.translation_rms < 2 * bound.translation_rms);
}

TEST_CASE("A rolling shutter's readout time is recovered with the poses at the noise floor") {
  // The arc's cameras move while their rows are read out in 30 ms: 0.5 rad/s
  // and 1 unit/s (the scene is 5 away), up to about 8 px at the image edges.
  constexpr double kReadout = 0.03;
  const testing::SyntheticScene scene = ArcScene(0, 3);
  BundleProblem truth = BundleProblemFromScene(scene);
  std::mt19937 rng(4);
  std::normal_distribution<double> noise(0, kNoisePx);
  for (BundleImage& image : truth.images) {
    image.angular_velocity = 0.5 * testing::RandomUnitVector(rng);
    image.linear_velocity = testing::RandomUnitVector(rng);
  }
  truth.cameras[0].readout_time = kReadout;
  for (BundleObservation& obs : truth.observations) {
    // The pixel depends on its own row's time: a fixed point, reached to
    // far below the noise in a few steps.
    const BundleImage& image = truth.images[obs.image];
    const Eigen::Vector3d in_cam = image.cam_from_world * truth.points[obs.point];
    for (int i = 0; i < 5; ++i) {
      obs.pixel = truth.cameras[0].ImgFromCam(truth.cameras[0].InCamAtRow(
          in_cam, obs.pixel.y(), image.angular_velocity, image.linear_velocity));
    }
    obs.pixel += Eigen::Vector2d(noise(rng), noise(rng));
  }

  BundleProblem rolling = truth;
  rolling.cameras[0].readout_time = 0;
  rolling.images[0].constant_pose = true;
  rolling.images[1].constant_pose = true;
  Perturb(17, 2, &rolling);
  BundleProblem still = rolling;
  for (BundleImage& image : still.images) {
    image.angular_velocity.setZero();
    image.linear_velocity.setZero();
  }

  BundleAdjuster::Options options;
  options.refine_readout_time = true;
  const BundleAdjuster::Summary summary = BundleAdjuster(options).Solve(&rolling);
  INFO(summary.BriefReport());
  REQUIRE(summary.termination == BundleAdjuster::Termination::kConvergence);
  const BundleAdjuster::Summary still_summary = BundleAdjuster(options).Solve(&still);
  INFO(still_summary.BriefReport());
  // The readout moves points by up to ~8 px; 0.5 px noise over ~50 000
  // observations pins it far better than 2 %.
  CHECK(rolling.cameras[0].readout_time == Approx(kReadout).epsilon(0.02));
  // Modelled, the residuals fall to the noise; a still camera's model leaves
  // the motion in them, and in the poses.
  CHECK(std::abs(RmsReprojectionError(rolling) - kNoisePx) < 0.1 * kNoisePx);
  CHECK(RmsReprojectionError(still) > 1.1 * RmsReprojectionError(rolling));
  CHECK(still.cameras[0].readout_time == 0);
  const PoseErrors errors = ComparePoses(rolling, scene, 2);
  const PoseErrors still_errors = ComparePoses(still, scene, 2);
  INFO("rolling " << errors.translation_rms << ", still " << still_errors.translation_rms);
  CHECK(errors.translation_rms < 0.25 * still_errors.translation_rms);
  CHECK(errors.rotation_rms_rad < 0.25 * still_errors.rotation_rms_rad);
}

TEST_CASE("The robust loss keeps 5% gross outliers from spoiling the poses") {
  const testing::SyntheticScene scene = ArcScene(kNoisePx, 2);
  BundleProblem clean = PerturbedArcProblem(scene);
  BundleProblem dirty = clean;
  std::mt19937 rng(3);
  std::bernoulli_distribution is_outlier(0.05);
  std::uniform_real_distribution<double> gross(10.0, 100.0);
  int num_outliers = 0;
  for (BundleObservation& obs : dirty.observations) {
    if (!is_outlier(rng)) continue;
    obs.pixel += gross(rng) * testing::RandomUnitVector(rng).head<2>().normalized();
    ++num_outliers;
  }
  REQUIRE(num_outliers > 0.04 * dirty.observations.size());

  const BundleAdjuster adjuster({});
  REQUIRE(adjuster.Solve(&clean).IsSolutionUsable());
  REQUIRE(adjuster.Solve(&dirty).IsSolutionUsable());
  const PoseErrors clean_errors = ComparePoses(clean, scene, 2);
  const PoseErrors dirty_errors = ComparePoses(dirty, scene, 2);
  INFO("clean " << clean_errors.rotation_rms_rad << " rad, "
                << clean_errors.translation_rms << "; with outliers "
                << dirty_errors.rotation_rms_rad << " rad, "
                << dirty_errors.translation_rms);
  CHECK(dirty_errors.rotation_rms_rad < 2 * clean_errors.rotation_rms_rad);
  CHECK(dirty_errors.translation_rms < 2 * clean_errors.translation_rms);
}

TEST_CASE("A focal length 5% off is recovered when refined, and only it") {
  Camera camera = Camera::FromFocal(CameraModelId::kSimpleRadial, 500, 640, 480);
  camera.params[3] = -0.05;
  const testing::SyntheticScene scene = ArcScene(kNoisePx, 4, camera);
  BundleProblem problem = PerturbedArcProblem(scene);
  problem.cameras[0].params[0] *= 1.05;
  const std::vector<double> start = problem.cameras[0].params;

  BundleAdjuster::Options options;
  SECTION("refined") {
    options.refine_focal_length = true;
    REQUIRE(BundleAdjuster(options).Solve(&problem).IsSolutionUsable());
    CHECK(std::abs(problem.cameras[0].params[0] / camera.params[0] - 1) < 0.005);
  }
  SECTION("held") {
    REQUIRE(BundleAdjuster(options).Solve(&problem).IsSolutionUsable());
    CHECK(problem.cameras[0].params[0] == start[0]);
  }
  // The principal point and distortion are held in both cases.
  for (int i = 1; i < 4; ++i) CHECK(problem.cameras[0].params[i] == start[i]);
}

TEST_CASE("Refined intrinsics stay within their bounds, inside them they converge") {
  // The truth: focal 500, principal point 30 px right of the centre (4.7 %
  // of the width).
  Camera camera = Camera::FromFocal(CameraModelId::kSimpleRadial, 500, 640, 480);
  camera.params[1] += 30;
  const testing::SyntheticScene scene = ArcScene(kNoisePx, 5, camera);
  BundleProblem problem = PerturbedArcProblem(scene);
  problem.cameras[0].params[1] -= 30;  // the start: the centre
  BundleAdjuster::Options options;
  options.refine_focal_length = true;
  options.refine_principal_point = true;
  SECTION("a focal length 30 % off with 1.2 allowed ends on its bound") {
    problem.cameras[0].params[1] += 30;
    problem.cameras[0].params[0] = 500 * 1.3;
    options.max_focal_length_change = 1.2;
    options.max_num_iterations = 10;
    const BundleAdjuster::Summary summary = BundleAdjuster(options).Solve(&problem);
    INFO(summary.BriefReport());
    REQUIRE(summary.IsSolutionUsable());
    CHECK(problem.cameras[0].params[0] == Approx(500 * 1.3 / 1.2).epsilon(1e-9));
  }
  SECTION("a principal point farther than allowed ends on its bound") {
    options.max_principal_point_offset = 0.02;  // 12.8 px
    options.max_num_iterations = 10;
    const BundleAdjuster::Summary summary = BundleAdjuster(options).Solve(&problem);
    INFO(summary.BriefReport());
    REQUIRE(summary.IsSolutionUsable());
    CHECK(problem.cameras[0].params[1] == Approx(319.5 + 12.8).epsilon(1e-9));
  }
  SECTION("the defaults") {
    problem.cameras[0].params[0] = 500 * 1.05;
    REQUIRE(BundleAdjuster(options).Solve(&problem).IsSolutionUsable());
    CHECK(std::abs(problem.cameras[0].params[0] / 500 - 1) < 0.005);
    CHECK(std::abs(problem.cameras[0].params[1] - camera.params[1]) < 1.0);
  }
}

TEST_CASE("Every camera model converges to the exact noise-free solution") {
  const std::vector<std::string> models = {
      "SIMPLE_PINHOLE 500,320,240",
      "PINHOLE 500,505,320,240",
      "SIMPLE_RADIAL 500,320,240,-0.05",
      "RADIAL 500,320,240,-0.05,0.01",
      "OPENCV 500,505,320,240,-0.05,0.01,0.001,-0.001",
      "FULL_OPENCV 500,505,320,240,-0.05,0.01,0.001,-0.001,0.001,0.01,0,0"};
  for (const std::string& model : models) {
    testing::SyntheticSceneOptions scene_options;
    scene_options.num_images = 8;
    scene_options.num_points = 200;
    scene_options.camera = Camera::FromString(model, 640, 480);
    const testing::SyntheticScene scene = testing::MakeSyntheticScene(scene_options);
    BundleProblem problem = PerturbedArcProblem(scene);
    BundleAdjuster::Options options;
    options.function_tolerance = 0;
    options.parameter_tolerance = 1e-12;
    const BundleAdjuster::Summary summary = BundleAdjuster(options).Solve(&problem);
    INFO(model << ": " << summary.BriefReport());
    CHECK(summary.IsSolutionUsable());
    CHECK(summary.final_mean_reprojection_error_px < 1e-6);
    const PoseErrors errors = ComparePoses(problem, scene, 2);
    CHECK(errors.rotation_rms_rad < 1e-8);
    CHECK(errors.translation_rms < 1e-8);
  }
}

TEST_CASE("The minimal gauge holds the first pose and one translation axis") {
  testing::SyntheticSceneOptions scene_options;
  scene_options.num_images = 10;
  scene_options.num_points = 300;
  const testing::SyntheticScene scene = testing::MakeSyntheticScene(scene_options);
  BundleProblem problem = BundleProblemFromScene(scene);
  Perturb(5, 1, &problem);
  const Rigid3d second = problem.images[1].cam_from_world;
  BundleAdjuster::Options options;
  options.function_tolerance = 0;
  options.parameter_tolerance = 1e-12;
  REQUIRE(BundleAdjuster(options).Solve(&problem).IsSolutionUsable());

  const Rigid3d& first = problem.images[0].cam_from_world;
  CHECK(first.rotation.coeffs() == scene.cams_from_world[0].rotation.coeffs());
  CHECK(first.translation == scene.cams_from_world[0].translation);
  // The held axis is the one scaling about the first camera moves most.
  Eigen::Index axis;
  (second.rotation * (ProjectionCenter(second) - ProjectionCenter(first)))
      .cwiseAbs()
      .maxCoeff(&axis);
  CHECK(problem.images[1].cam_from_world.translation[axis] == second.translation[axis]);
  // Noise-free: the solution is the truth scaled about the first camera so
  // that the held component keeps its perturbed value; it reprojects exactly.
  CHECK(RmsReprojectionError(problem) < 1e-6);
}

// The block in another similarity frame, world x' = s R x + t: each camera
// frame scales by s, so the pixels stay as they are.
BundleProblem InFrame(BundleProblem block, double s, const Eigen::Quaterniond& r,
                      const Eigen::Vector3d& t) {
  for (Eigen::Vector3d& point : block.points) point = s * (r * point) + t;
  for (BundleImage& image : block.images) {
    Rigid3d& pose = image.cam_from_world;
    pose.rotation = (pose.rotation * r.conjugate()).normalized();
    pose.translation = s * pose.translation - pose.rotation * t;
  }
  return block;
}

// `block` after what `problem` holds, its indices shifted past it.
void AppendBlock(const BundleProblem& block, BundleProblem* problem) {
  const int num_cameras = static_cast<int>(problem->cameras.size());
  const int num_images = static_cast<int>(problem->images.size());
  const int num_points = static_cast<int>(problem->points.size());
  problem->cameras.insert(problem->cameras.end(), block.cameras.begin(),
                          block.cameras.end());
  for (BundleImage image : block.images) {
    image.camera += num_cameras;
    problem->images.push_back(image);
  }
  problem->points.insert(problem->points.end(), block.points.begin(), block.points.end());
  for (BundleObservation obs : block.observations) {
    obs.image += num_images;
    obs.point += num_points;
    problem->observations.push_back(obs);
  }
}

// RMS per image axis of the observations [begin, end).
double RmsOf(const std::vector<double>& errors, size_t begin, size_t end) {
  double sum = 0;
  for (size_t o = begin; o < end; ++o) sum += errors[o] * errors[o];
  return std::sqrt(sum / (2.0 * (end - begin)));
}

// The translation axis the minimal gauge holds for scale in `image`: the
// one scaling about `anchor`'s centre moves most.
Eigen::Index ScaleAxis(const Rigid3d& image, const Rigid3d& anchor) {
  Eigen::Index axis;
  (image.rotation * (ProjectionCenter(image) - ProjectionCenter(anchor)))
      .cwiseAbs()
      .maxCoeff(&axis);
  return axis;
}

TEST_CASE("The minimal gauge holds each disconnected block in its own frame") {
  // Two blocks with nothing in common (cameras, points, observers), the
  // second in a frame scaled by 3, turned and moved: one global BA over both.
  testing::SyntheticSceneOptions scene_options;
  scene_options.num_images = 10;
  scene_options.num_points = 300;
  scene_options.noise_px = kNoisePx;
  scene_options.seed = 7;
  BundleProblem first = BundleProblemFromScene(testing::MakeSyntheticScene(scene_options));
  Perturb(8, 1, &first);
  scene_options.seed = 9;
  scene_options.camera = Camera::FromFocal(CameraModelId::kSimpleRadial, 600, 800, 600);
  BundleProblem second = BundleProblemFromScene(testing::MakeSyntheticScene(scene_options));
  Perturb(10, 1, &second);
  std::mt19937 rng(11);
  second = InFrame(second, 3.0, testing::RandomRotation(rng), Eigen::Vector3d(20, -5, 8));
  // Held, the second block's third pose takes the place of its first as the
  // anchor; the scale is still free about it.
  const bool second_has_constant_pose = GENERATE(false, true);
  const int second_anchor = second_has_constant_pose ? 2 : 0;
  const int second_scale_image = second_has_constant_pose ? 0 : 1;
  second.images[second_anchor].constant_pose = second_has_constant_pose;

  BundleProblem both = first;
  AppendBlock(second, &both);
  const int n = static_cast<int>(first.images.size());
  const size_t first_observations = first.observations.size();
  const BundleProblem start = both;

  // Least squares, so that the residuals at the minimum follow from the noise
  // alone; tight tolerances, so that each solve ends at its minimum.
  BundleAdjuster::Options options;
  options.loss = BundleAdjuster::Options::Loss::kTrivial;
  options.function_tolerance = 1e-12;
  options.parameter_tolerance = 1e-12;
  const BundleAdjuster adjuster(options);
  const BundleAdjuster::Summary summary = adjuster.Solve(&both);
  INFO(summary.BriefReport());
  REQUIRE(summary.termination == BundleAdjuster::Termination::kConvergence);
  // One pose held per block, the caller's or the gauge's.
  CHECK(summary.num_free_images == 18);

  // Each block's anchor exactly as it was, and the scale component of another
  // of its images.
  for (const auto& [anchor, scale_image] :
       {std::pair{0, 1}, std::pair{n + second_anchor, n + second_scale_image}}) {
    INFO("anchor " << anchor << ", scale image " << scale_image);
    const Rigid3d& held = both.images[anchor].cam_from_world;
    CHECK(held.rotation.coeffs() == start.images[anchor].cam_from_world.rotation.coeffs());
    CHECK(held.translation == start.images[anchor].cam_from_world.translation);
    const Rigid3d& before = start.images[scale_image].cam_from_world;
    const Rigid3d& after = both.images[scale_image].cam_from_world;
    const Eigen::Index axis = ScaleAxis(before, start.images[anchor].cam_from_world);
    CHECK(after.translation[axis] == before.translation[axis]);
    // The rest of that pose is refined.
    CHECK(after.rotation.angularDistance(before.rotation) > 1e-4);
  }

  // Each block alone: the same start and the same gauge, so the same
  // minimum.
  REQUIRE(adjuster.Solve(&first).termination == BundleAdjuster::Termination::kConvergence);
  REQUIRE(adjuster.Solve(&second).termination == BundleAdjuster::Termination::kConvergence);
  const std::vector<double> errors = ReprojectionErrors(both);
  for (const auto& [block, begin, end] :
       {std::tuple{&first, size_t{0}, first_observations},
        std::tuple{&second, first_observations, errors.size()}}) {
    // At the least-squares minimum the residual RMS per axis is
    // sigma sqrt(1 - p / m), p the block's parameters less its 7 gauge DoF,
    // m = 2N its residuals; over noise draws it spreads by sigma / (2 sqrt N).
    const double num_observations = double(end - begin);
    std::vector<char> point_observed(block->points.size(), 0);
    for (const BundleObservation& obs : block->observations) point_observed[obs.point] = 1;
    const double num_parameters =
        6.0 * block->images.size() +
        3.0 * std::count(point_observed.begin(), point_observed.end(), 1) - 7;
    const double floor = kNoisePx * std::sqrt(1 - num_parameters / (2 * num_observations));
    const double spread = kNoisePx / (2 * std::sqrt(num_observations));
    const double joint_rms = RmsOf(errors, begin, end);
    const double alone_rms = RmsReprojectionError(*block);
    INFO("joint " << joint_rms << " px, alone " << alone_rms << " px, floor " << floor
                  << " px, spread " << spread << " px");
    CHECK(std::abs(joint_rms - floor) < 3 * spread);
    // The same minimum: far closer than the noise could tell apart.
    CHECK(std::abs(joint_rms - alone_rms) < 1e-3 * spread);
  }
}

TEST_CASE("Dense, sparse and iterative Schur reach the same minimum") {
  testing::SyntheticSceneOptions scene_options;
  scene_options.num_images = 12;
  scene_options.num_points = 300;
  scene_options.noise_px = kNoisePx;
  const testing::SyntheticScene scene = testing::MakeSyntheticScene(scene_options);
  const BundleProblem start = PerturbedArcProblem(scene);

  struct Case {
    double iterative_min_track_length;
    int dense_max;
    int sparse_max;
    const char* solver;
  };
  std::vector<BundleProblem> solutions;
  // Every point is seen by most of the 12 images: tracks of about 12.
  for (const Case& c : {Case{50, 50, 1000, "DENSE_SCHUR"}, Case{50, 5, 1000, "SPARSE_SCHUR"},
                        Case{50, 2, 5, "ITERATIVE_SCHUR"}, Case{5, 50, 1000, "ITERATIVE_SCHUR"}}) {
    BundleAdjuster::Options options;
    options.iterative_schur_min_track_length = c.iterative_min_track_length;
    options.dense_schur_max_images = c.dense_max;
    options.sparse_schur_max_images = c.sparse_max;
    options.function_tolerance = 1e-12;
    BundleProblem problem = start;
    const BundleAdjuster::Summary summary = BundleAdjuster(options).Solve(&problem);
    CHECK(summary.linear_solver == c.solver);
    CHECK(summary.IsSolutionUsable());
    solutions.push_back(problem);
  }
  for (size_t s = 1; s < solutions.size(); ++s) {
    for (size_t i = 0; i < start.images.size(); ++i) {
      const Rigid3d& a = solutions[0].images[i].cam_from_world;
      const Rigid3d& b = solutions[s].images[i].cam_from_world;
      CHECK(a.rotation.angularDistance(b.rotation) < 1e-7);
      CHECK((a.translation - b.translation).norm() < 1e-6);
    }
  }
}

TEST_CASE("Points seen only by constant images stay constant") {
  testing::SyntheticSceneOptions scene_options;
  scene_options.num_images = 6;
  scene_options.num_points = 100;
  scene_options.noise_px = kNoisePx;
  const testing::SyntheticScene scene = testing::MakeSyntheticScene(scene_options);
  BundleProblem problem = BundleProblemFromScene(scene);
  // Point 0 loses its observations in the free images 3..5.
  std::vector<BundleObservation> kept;
  for (const BundleObservation& obs : problem.observations) {
    if (obs.point != 0 || obs.image < 3) kept.push_back(obs);
  }
  problem.observations = kept;
  for (int i = 0; i < 3; ++i) problem.images[i].constant_pose = true;
  Perturb(6, 3, &problem);
  const BundleProblem before = problem;

  const BundleAdjuster::Summary summary = BundleAdjuster({}).Solve(&problem);
  REQUIRE(summary.IsSolutionUsable());
  CHECK(summary.num_free_points == 99);
  CHECK(problem.points[0] == before.points[0]);
  CHECK(problem.points[1] != before.points[1]);
  for (int i = 0; i < 3; ++i) {
    CHECK(problem.images[i].cam_from_world.translation ==
          before.images[i].cam_from_world.translation);
  }
}

// 8 images and 200 points, perturbed: a solve of several iterations.
BundleProblem SmallPerturbedProblem() {
  testing::SyntheticSceneOptions scene_options;
  scene_options.num_images = 8;
  scene_options.num_points = 200;
  return PerturbedArcProblem(testing::MakeSyntheticScene(scene_options));
}

TEST_CASE("An iteration limit ends the solve early with a usable result") {
  BundleProblem problem = SmallPerturbedProblem();
  BundleAdjuster::Options options;
  options.max_num_iterations = 1;
  const BundleAdjuster::Summary summary = BundleAdjuster(options).Solve(&problem);
  CHECK(summary.termination == BundleAdjuster::Termination::kNoConvergence);
  CHECK(summary.IsSolutionUsable());
  CHECK(summary.num_iterations == 1);
  CHECK(summary.final_cost < summary.initial_cost);
  CHECK(summary.final_mean_reprojection_error_px <
        summary.initial_mean_reprojection_error_px);
}

TEST_CASE("should_stop ends the solve after the iteration it turns true in, usable") {
  BundleProblem problem = SmallPerturbedProblem();
  BundleAdjuster::Options options;
  int polls = 0;
  // Ceres polls once after evaluating the start (iteration 0), then after
  // each iteration.
  options.should_stop = [&polls] { return ++polls == 3; };
  const BundleAdjuster::Summary summary = BundleAdjuster(options).Solve(&problem);
  CHECK(polls == 3);
  CHECK(summary.num_iterations == 2);
  CHECK(summary.termination == BundleAdjuster::Termination::kNoConvergence);
  CHECK(summary.IsSolutionUsable());
  CHECK(summary.final_cost < summary.initial_cost);
}

TEST_CASE("Options are checked") {
  BundleAdjuster::Options options;
  CHECK(options.Check());
  options.loss_scale_px = 0;
  CHECK_FALSE(options.Check());
  options = {};
  options.sparse_schur_max_images = options.dense_schur_max_images - 1;
  CHECK_FALSE(options.Check());
  options = {};
  options.num_threads = 0;
  CHECK_FALSE(options.Check());
  options = {};
  options.max_focal_length_change = 1;
  CHECK_FALSE(options.Check());
  options = {};
  options.max_principal_point_offset = 0.5;
  CHECK_FALSE(options.Check());
}

}  // namespace
}  // namespace flysfm
