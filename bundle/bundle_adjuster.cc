#include "bundle/bundle_adjuster.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <memory>
#include <sstream>
#include <vector>

#include <ceres/ceres.h>

#include "bundle/cost_functions.h"
#include "geometry/check.h"

namespace flysfm {
namespace {

using Clock = std::chrono::steady_clock;
using Matrix2x6d = Eigen::Matrix<double, 2, 6>;
using Matrix6x3d = Eigen::Matrix<double, 6, 3>;
using RowMatrix2x3d = Eigen::Matrix<double, 2, 3, Eigen::RowMajor>;
using RowMatrix2x4d = Eigen::Matrix<double, 2, 4, Eigen::RowMajor>;
using RowMatrix4x3d = Eigen::Matrix<double, 4, 3, Eigen::RowMajor>;

double SecondsSince(Clock::time_point start) {
  return std::chrono::duration<double>(Clock::now() - start).count();
}

// One observation as it entered the Ceres problem.
struct AddedResidual {
  int observation = 0;
  ceres::CostFunction* cost = nullptr;  // owned by the Ceres problem
  std::vector<double*> blocks;
  bool pose_free = false;
  // blocks[point_block] is the point (after the pose's two blocks, if any).
  int point_block = 0;

  bool HasPoseBlocks() const { return point_block > 0; }
};

// A translation component held for scale.
struct ScaleHold {
  int image = -1;
  int axis = -1;
};

// The poses held constant for the solve (the problem's flags plus the gauge)
// and the translation components held for scale, at most one per connected
// block.
struct GaugeChoice {
  std::vector<char> constant_pose;
  std::vector<ScaleHold> scale_holds;
};

// Union-find over images, with path halving.
class ImageComponents {
 public:
  explicit ImageComponents(int num_images) : parent_(num_images) {
    for (int i = 0; i < num_images; ++i) parent_[i] = i;
  }
  int Find(int i) {
    while (parent_[i] != i) {
      parent_[i] = parent_[parent_[i]];
      i = parent_[i];
    }
    return i;
  }
  void Join(int a, int b) { parent_[Find(a)] = Find(b); }

 private:
  std::vector<int> parent_;
};

// The blocks of images that share a similarity gauge: joined by the points
// the solve refines, since a similarity of the world that moves such a point
// has to move every image observing it alike. A point the solve holds joins
// nothing: it is held only when all its observers' poses are held
// (ChooseFreeParameters), so it never meets a refined pose and has no
// freedom to share; joining through it would count the constant poses of
// two blocks together and leave each block's scale free. (Were a held point
// seen from a refined block, it still would not hold that block's gauge: a
// similarity fixing one point keeps 4 of its 7 DoF.) Intrinsics join nothing
// either: a similarity of the world leaves them as they are, so a camera
// shared by two blocks ties none of their gauges.
ImageComponents ConnectImages(const BundleProblem& problem) {
  const int num_images = static_cast<int>(problem.images.size());
  std::vector<char> point_refined(problem.points.size(), 0);
  for (const BundleObservation& obs : problem.observations) {
    if (!problem.images[obs.image].constant_pose) point_refined[obs.point] = 1;
  }
  ImageComponents components(num_images);
  std::vector<int> first_observer(problem.points.size(), -1);
  for (const BundleObservation& obs : problem.observations) {
    if (!point_refined[obs.point]) continue;
    int& first = first_observer[obs.point];
    if (first < 0) {
      first = obs.image;
    } else {
      components.Join(first, obs.image);
    }
  }
  return components;
}

// Gauge::kMinimal per block of ConnectImages: the blocks move apart without
// changing a residual, so each is free in its own 7 DoF and its constant
// poses hold its gauge only. A block with two or more constant poses needs
// nothing; one with a single constant pose is held by it but for scale about
// its centre; one with none has its first image's pose held. Either of the
// last two also holds, for scale, one translation component of another of
// its images.
GaugeChoice ChooseGauge(const BundleProblem& problem,
                        const std::vector<char>& observed,
                        BundleAdjuster::Options::Gauge gauge) {
  GaugeChoice choice;
  const int num_images = static_cast<int>(problem.images.size());
  choice.constant_pose.resize(num_images);
  for (int i = 0; i < num_images; ++i) {
    choice.constant_pose[i] = problem.images[i].constant_pose;
  }
  if (gauge != BundleAdjuster::Options::Gauge::kMinimal) return choice;

  ImageComponents components = ConnectImages(problem);
  // By component root: the observed constant poses, whether some observed
  // pose is refined, and the anchor (the first constant pose, else the first
  // observed image).
  std::vector<int> root(num_images, -1);
  std::vector<int> num_constant(num_images, 0);
  std::vector<char> has_refined(num_images, 0);
  std::vector<int> anchor(num_images, -1);
  for (int i = 0; i < num_images; ++i) {
    if (!observed[i]) continue;
    const int r = root[i] = components.Find(i);
    if (!choice.constant_pose[i]) {
      has_refined[r] = 1;
    } else if (num_constant[r]++ == 0) {
      anchor[r] = i;
    }
  }
  std::vector<char> needs_scale(num_images, 0);
  for (int i = 0; i < num_images; ++i) {
    if (!observed[i]) continue;
    const int r = root[i];
    if (!has_refined[r] || num_constant[r] >= 2) continue;
    needs_scale[r] = 1;
    if (anchor[r] < 0) {
      anchor[r] = i;
      choice.constant_pose[i] = true;
    }
  }
  // Scaling the world about the anchor's centre a moves t_i by
  // R_i (c_i - a) per unit of log-scale: hold the component it moves most.
  for (int i = 0; i < num_images; ++i) {
    if (!observed[i] || choice.constant_pose[i]) continue;
    const int r = root[i];
    if (!needs_scale[r]) continue;
    const Eigen::Vector3d a =
        ProjectionCenter(problem.images[anchor[r]].cam_from_world);
    const Rigid3d& pose = problem.images[i].cam_from_world;
    const Eigen::Vector3d lever = pose.rotation * (ProjectionCenter(pose) - a);
    if (lever.norm() <= 1e-12 * (1.0 + a.norm())) continue;
    ScaleHold hold;
    hold.image = i;
    lever.cwiseAbs().maxCoeff(&hold.axis);
    choice.scale_holds.push_back(hold);
    needs_scale[r] = 0;
  }
  return choice;
}

std::unique_ptr<ceres::LossFunction> MakeLoss(
    const BundleAdjuster::Options& options) {
  using Loss = BundleAdjuster::Options::Loss;
  switch (options.loss) {
    case Loss::kTrivial: return nullptr;
    case Loss::kHuber:
      return std::make_unique<ceres::HuberLoss>(options.loss_scale_px);
    case Loss::kCauchy:
      return std::make_unique<ceres::CauchyLoss>(options.loss_scale_px);
  }
  FLYSFM_CHECK(false);
  return nullptr;
}

// Indices of a camera's parameters that stay constant under the options.
std::vector<int> ConstantIntrinsics(const Camera& camera,
                                    const BundleAdjuster::Options& options) {
  std::vector<int> constant;
  const int num_focal = camera.NumFocalParams();
  for (int i = 0; i < camera.NumParams(); ++i) {
    const bool refined = i < num_focal ? options.refine_focal_length
                         : i < num_focal + 2 ? options.refine_principal_point
                                             : options.refine_extra_params;
    if (!refined) constant.push_back(i);
  }
  return constant;
}

// The information each weighted image's pose has from its own observations
// in the reduced camera system (paper Eq. 5) at the start: the 6x6 diagonal
// block S_ii = H_ii - sum_p W_ip V_p^+ W_ip^T, in the tangent coordinates of
// the pose blocks, with robust-loss weights rho'(s). See docs/bundle.md.
std::vector<Matrix6d> WeightedPoseInformation(
    const BundleProblem& problem, const std::vector<AddedResidual>& residuals,
    const std::vector<char>& weighted, const std::vector<char>& point_free,
    const ceres::LossFunction* loss) {
  const int num_points = static_cast<int>(problem.points.size());
  std::vector<char> linked(num_points, 0);
  for (const AddedResidual& residual : residuals) {
    const BundleObservation& obs = problem.observations[residual.observation];
    if (residual.pose_free && weighted[obs.image]) linked[obs.point] = 1;
  }

  std::vector<Matrix6d> information(problem.images.size(), Matrix6d::Zero());
  std::vector<Eigen::Matrix3d> point_information(num_points,
                                                 Eigen::Matrix3d::Zero());
  struct Coupling {
    int image;
    int point;
    Matrix6x3d w;
  };
  std::vector<Coupling> couplings;
  const ceres::EigenQuaternionManifold quaternion_manifold;

  Eigen::Vector2d r;
  RowMatrix2x4d j_rotation;
  RowMatrix2x3d j_translation;
  RowMatrix2x3d j_point;
  RowMatrix4x3d plus_jacobian;
  for (const AddedResidual& residual : residuals) {
    const BundleObservation& obs = problem.observations[residual.observation];
    if (!linked[obs.point]) continue;
    const bool pose_wanted = residual.pose_free && weighted[obs.image];
    std::vector<double*> jacobians(residual.blocks.size(), nullptr);
    if (pose_wanted) {
      jacobians[0] = j_rotation.data();
      jacobians[1] = j_translation.data();
    }
    jacobians[residual.point_block] = j_point.data();
    if (!residual.cost->Evaluate(residual.blocks.data(), r.data(),
                                 jacobians.data())) {
      continue;
    }
    double weight = 1.0;
    if (loss != nullptr) {
      double rho[3];
      loss->Evaluate(r.squaredNorm(), rho);
      weight = rho[1];
    }
    if (point_free[obs.point]) {
      point_information[obs.point] += weight * j_point.transpose() * j_point;
    }
    if (!pose_wanted) continue;
    quaternion_manifold.PlusJacobian(residual.blocks[0], plus_jacobian.data());
    Matrix2x6d j_pose;
    j_pose << j_rotation * plus_jacobian, j_translation;
    information[obs.image] += weight * j_pose.transpose() * j_pose;
    if (point_free[obs.point]) {
      couplings.push_back(
          {obs.image, obs.point, weight * j_pose.transpose() * j_point});
    }
  }

  std::vector<Eigen::Matrix3d> point_covariance(num_points);
  for (int p = 0; p < num_points; ++p) {
    if (!linked[p] || !point_free[p]) continue;
    // Pseudo-inverse: a point seen once has a rank-2 information.
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eigen(
        point_information[p]);
    const Eigen::Vector3d values = eigen.eigenvalues();
    Eigen::Vector3d inverse = Eigen::Vector3d::Zero();
    for (int k = 0; k < 3; ++k) {
      if (values[k] > 1e-12 * values.maxCoeff()) inverse[k] = 1.0 / values[k];
    }
    point_covariance[p] =
        eigen.eigenvectors() * inverse.asDiagonal() * eigen.eigenvectors().transpose();
  }
  for (const Coupling& c : couplings) {
    information[c.image] -= c.w * point_covariance[c.point] * c.w.transpose();
  }
  return information;
}

// sqrt((p - 1) S): a 6x6 L with L^T L = (p - 1) S, S clamped to PSD.
Matrix6d PriorSqrtInformation(const Matrix6d& information, double weight) {
  const Eigen::SelfAdjointEigenSolver<Matrix6d> eigen(
      0.5 * (information + information.transpose()));
  const Eigen::Matrix<double, 6, 1> root =
      eigen.eigenvalues().cwiseMax(0.0).cwiseSqrt() * std::sqrt(weight - 1.0);
  return root.asDiagonal() * eigen.eigenvectors().transpose();
}

// Options::on_iteration and Options::should_stop, after each iteration.
class IterationCallback : public ceres::IterationCallback {
 public:
  explicit IterationCallback(const BundleAdjuster::Options& options) : options_(options) {}
  ceres::CallbackReturnType operator()(const ceres::IterationSummary& summary) override {
    if (options_.on_iteration) options_.on_iteration(summary.iteration);
    return options_.should_stop && options_.should_stop() ? ceres::SOLVER_TERMINATE_SUCCESSFULLY
                                                          : ceres::SOLVER_CONTINUE;
  }

 private:
  const BundleAdjuster::Options& options_;
};

BundleAdjuster::Termination ToTermination(const ceres::Solver::Summary& summary) {
  if (!summary.IsSolutionUsable()) return BundleAdjuster::Termination::kFailure;
  switch (summary.termination_type) {
    case ceres::CONVERGENCE: return BundleAdjuster::Termination::kConvergence;
    // Only Options::should_stop ends a solve this way.
    case ceres::USER_SUCCESS:
    case ceres::NO_CONVERGENCE: return BundleAdjuster::Termination::kNoConvergence;
    default: return BundleAdjuster::Termination::kFailure;
  }
}

const char* TerminationName(BundleAdjuster::Termination termination) {
  switch (termination) {
    case BundleAdjuster::Termination::kConvergence: return "convergence";
    case BundleAdjuster::Termination::kNoConvergence: return "no convergence";
    case BundleAdjuster::Termination::kFailure: return "failure";
  }
  return "?";
}

double MeanReprojectionError(const BundleProblem& problem,
                             const std::vector<AddedResidual>& residuals) {
  if (residuals.empty()) return 0.0;
  double sum = 0.0;
  for (const AddedResidual& residual : residuals) {
    sum += ReprojectionError(problem, problem.observations[residual.observation]);
  }
  return sum / residuals.size();
}

// Sum n^2 / sum n, n a point's observations from refined poses: the mean
// track length an observation belongs to, which sets the Schur complement's
// cost per observation.
double WeightedMeanTrackLength(const BundleProblem& problem,
                               const std::vector<AddedResidual>& residuals) {
  std::vector<int> track_length(problem.points.size(), 0);
  double sum = 0;
  for (const AddedResidual& residual : residuals) {
    if (!residual.pose_free) continue;
    ++track_length[problem.observations[residual.observation].point];
    ++sum;
  }
  double sum_squares = 0;
  for (const int n : track_length) sum_squares += double(n) * n;
  return sum > 0 ? sum_squares / sum : 0;
}

// What the solve refines, decided before any block enters Ceres.
struct FreeParameters {
  GaugeChoice gauge;
  std::vector<char> point_observed;
  // Observed from a refined pose.
  std::vector<char> point_free;
  std::vector<std::vector<int>> constant_intrinsics;
  // Some of the camera's intrinsics are refined.
  std::vector<char> camera_free;
  std::vector<char> readout_free;
};

FreeParameters ChooseFreeParameters(const BundleProblem& problem,
                                    const BundleAdjuster::Options& options) {
  const int num_images = static_cast<int>(problem.images.size());
  const int num_points = static_cast<int>(problem.points.size());
  const int num_cameras = static_cast<int>(problem.cameras.size());
  FreeParameters free_parameters;
  std::vector<char> image_observed(num_images, 0);
  free_parameters.point_observed.assign(num_points, 0);
  for (const BundleObservation& obs : problem.observations) {
    image_observed[obs.image] = 1;
    free_parameters.point_observed[obs.point] = 1;
  }
  free_parameters.gauge = ChooseGauge(problem, image_observed, options.gauge);
  free_parameters.point_free.assign(num_points, 0);
  for (const BundleObservation& obs : problem.observations) {
    if (!free_parameters.gauge.constant_pose[obs.image]) {
      free_parameters.point_free[obs.point] = 1;
    }
  }
  free_parameters.constant_intrinsics.resize(num_cameras);
  free_parameters.camera_free.assign(num_cameras, 0);
  for (int c = 0; c < num_cameras; ++c) {
    free_parameters.constant_intrinsics[c] =
        ConstantIntrinsics(problem.cameras[c], options);
    free_parameters.camera_free[c] = free_parameters.constant_intrinsics[c].size() <
                                     problem.cameras[c].params.size();
  }
  // A readout time is observable only through moving images.
  free_parameters.readout_free.assign(num_cameras, 0);
  if (options.refine_readout_time) {
    for (const BundleImage& image : problem.images) {
      if (image.IsMoving()) free_parameters.readout_free[image.camera] = 1;
    }
  }
  return free_parameters;
}

ceres::Problem::Options ProblemOptionsOwningCostsOnly() {
  ceres::Problem::Options options;
  options.loss_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  options.manifold_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  return options;
}

// The Ceres problem with what it refers to and does not own: the loss, the
// manifolds and the ordering that eliminates the points first. The problem
// is declared last so that it is destroyed first.
struct CeresProblem {
  explicit CeresProblem(const BundleAdjuster::Options& options)
      : loss(MakeLoss(options)),
        ordering(std::make_shared<ceres::ParameterBlockOrdering>()),
        problem(ProblemOptionsOwningCostsOnly()) {}

  const std::unique_ptr<ceres::LossFunction> loss;
  ceres::EigenQuaternionManifold quaternion_manifold;
  // By held axis, made when first needed; shared by the blocks holding it.
  std::unique_ptr<ceres::SubsetManifold> scale_manifolds[3];
  std::vector<std::unique_ptr<ceres::SubsetManifold>> intrinsics_manifolds;
  const std::shared_ptr<ceres::ParameterBlockOrdering> ordering;
  ceres::Problem problem;
};

// The reprojection residuals in the Ceres problem and the blocks they
// brought in.
struct AddedResiduals {
  std::vector<AddedResidual> residuals;
  // The image's pose blocks are refined.
  std::vector<char> image_added;
  // The image's pose blocks are in the problem, held constant.
  std::vector<char> pose_block_held;
  std::vector<char> camera_added;
};

// Observation `o`'s residual, from the cost function that fits what of its
// image is refined.
AddedResidual MakeReprojectionResidual(int o, bool pose_free, bool readout_free,
                                       BundleProblem* problem) {
  const BundleObservation& obs = problem->observations[o];
  BundleImage& image = problem->images[obs.image];
  Camera& camera = problem->cameras[image.camera];
  AddedResidual residual;
  residual.observation = o;
  residual.pose_free = pose_free;
  if (image.IsMoving() && (pose_free || readout_free)) {
    // A held pose enters as constant blocks where the readout time is
    // refined: the folded constant-pose cost has none.
    residual.cost = CreateRollingShutterReprojectionCost(
        camera.model_id, obs.pixel, RowTimeFraction(obs.pixel.y(), camera.height),
        image.angular_velocity, image.linear_velocity);
    residual.blocks = {image.cam_from_world.rotation.coeffs().data(),
                       image.cam_from_world.translation.data(),
                       problem->points[obs.point].data(), camera.params.data(),
                       &camera.readout_time};
    residual.point_block = 2;
  } else if (pose_free) {
    residual.cost = CreateReprojectionCost(camera.model_id, obs.pixel);
    residual.blocks = {image.cam_from_world.rotation.coeffs().data(),
                       image.cam_from_world.translation.data(),
                       problem->points[obs.point].data(), camera.params.data()};
    residual.point_block = 2;
  } else {
    // A held rolling-shutter image's row time folds in with its pose: the
    // local BAs of a video hold most of their observers so. A still
    // image's zero velocities make its row time moot.
    residual.cost = CreateConstantPoseReprojectionCost(
        camera.model_id, image.cam_from_world, obs.pixel,
        RowTimeFraction(obs.pixel.y(), camera.height) * camera.readout_time,
        image.angular_velocity, image.linear_velocity);
    residual.blocks = {problem->points[obs.point].data(), camera.params.data()};
  }
  return residual;
}

// Every observation that touches something refined, in observation order,
// with the robust loss.
AddedResiduals AddReprojectionResiduals(const FreeParameters& free_parameters,
                                        BundleProblem* problem,
                                        CeresProblem* ceres_problem) {
  const int num_images = static_cast<int>(problem->images.size());
  AddedResiduals added;
  added.image_added.assign(num_images, 0);
  added.pose_block_held.assign(num_images, 0);
  added.camera_added.assign(problem->cameras.size(), 0);
  // The costs read a quaternion as a unit one and the manifold's steps keep
  // its norm: a refined rotation has to start normalised.
  for (int i = 0; i < num_images; ++i) {
    if (!free_parameters.gauge.constant_pose[i]) {
      problem->images[i].cam_from_world.rotation.normalize();
    }
  }
  for (int o = 0; o < static_cast<int>(problem->observations.size()); ++o) {
    const BundleObservation& obs = problem->observations[o];
    const int camera = problem->images[obs.image].camera;
    const bool pose_free = !free_parameters.gauge.constant_pose[obs.image];
    if (!pose_free && !free_parameters.point_free[obs.point] &&
        !free_parameters.camera_free[camera] && !free_parameters.readout_free[camera]) {
      continue;
    }
    AddedResidual residual = MakeReprojectionResidual(
        o, pose_free, free_parameters.readout_free[camera], problem);
    if (residual.HasPoseBlocks()) {
      added.image_added[obs.image] = pose_free;
      added.pose_block_held[obs.image] = !pose_free;
    }
    added.camera_added[camera] = 1;
    ceres_problem->problem.AddResidualBlock(residual.cost, ceres_problem->loss.get(),
                                            residual.blocks);
    added.residuals.push_back(std::move(residual));
  }
  return added;
}

// Refined poses on the quaternion manifold, the gauge's scale components held;
// held pose blocks constant. Returns the number of refined poses.
int SetPoseBlocks(const AddedResiduals& added, const GaugeChoice& gauge,
                  BundleProblem* problem, CeresProblem* ceres_problem) {
  const int num_images = static_cast<int>(problem->images.size());
  int num_free_images = 0;
  for (int i = 0; i < num_images; ++i) {
    if (!added.image_added[i]) continue;
    ++num_free_images;
    Rigid3d& pose = problem->images[i].cam_from_world;
    ceres_problem->problem.SetManifold(pose.rotation.coeffs().data(),
                                       &ceres_problem->quaternion_manifold);
    ceres_problem->ordering->AddElementToGroup(pose.rotation.coeffs().data(), 1);
    ceres_problem->ordering->AddElementToGroup(pose.translation.data(), 1);
  }
  for (const ScaleHold& hold : gauge.scale_holds) {
    if (!added.image_added[hold.image]) continue;
    std::unique_ptr<ceres::SubsetManifold>& manifold =
        ceres_problem->scale_manifolds[hold.axis];
    if (manifold == nullptr) {
      manifold = std::make_unique<ceres::SubsetManifold>(3, std::vector<int>{hold.axis});
    }
    ceres_problem->problem.SetManifold(
        problem->images[hold.image].cam_from_world.translation.data(), manifold.get());
  }
  for (int i = 0; i < num_images; ++i) {
    if (!added.pose_block_held[i]) continue;
    Rigid3d& pose = problem->images[i].cam_from_world;
    ceres_problem->problem.SetParameterBlockConstant(pose.rotation.coeffs().data());
    ceres_problem->problem.SetParameterBlockConstant(pose.translation.data());
    ceres_problem->ordering->AddElementToGroup(pose.rotation.coeffs().data(), 1);
    ceres_problem->ordering->AddElementToGroup(pose.translation.data(), 1);
  }
  return num_free_images;
}

// Free points are eliminated first; held ones are constant. Returns the
// number of free points.
int SetPointBlocks(const FreeParameters& free_parameters, BundleProblem* problem,
                   CeresProblem* ceres_problem) {
  int num_free_points = 0;
  for (int p = 0; p < static_cast<int>(problem->points.size()); ++p) {
    if (!free_parameters.point_observed[p]) continue;
    double* point = problem->points[p].data();
    if (!ceres_problem->problem.HasParameterBlock(point)) continue;
    if (free_parameters.point_free[p]) {
      ++num_free_points;
      ceres_problem->ordering->AddElementToGroup(point, 0);
    } else {
      ceres_problem->problem.SetParameterBlockConstant(point);
      ceres_problem->ordering->AddElementToGroup(point, 1);
    }
  }
  return num_free_points;
}

// A refined readout time within +-max_readout_time_seconds, widened to hold
// its start; a held one constant.
void SetReadoutBlock(bool readout_free, const BundleAdjuster::Options& options,
                     double* readout, CeresProblem* ceres_problem) {
  if (!ceres_problem->problem.HasParameterBlock(readout)) return;
  ceres_problem->ordering->AddElementToGroup(readout, 1);
  if (readout_free) {
    const double reach = options.max_readout_time_seconds;
    ceres_problem->problem.SetParameterLowerBound(readout, 0, std::min(*readout, -reach));
    ceres_problem->problem.SetParameterUpperBound(readout, 0, std::max(*readout, reach));
  } else {
    ceres_problem->problem.SetParameterBlockConstant(readout);
  }
}

// The safeguards of refined intrinsics (Options::max_focal_length_change,
// max_principal_point_offset) as bounds of the solve.
void BoundIntrinsics(const BundleAdjuster::Options& options, Camera* camera,
                     ceres::Problem* problem) {
  double* params = camera->params.data();
  const int num_focal = camera->NumFocalParams();
  if (options.refine_focal_length) {
    for (int i = 0; i < num_focal; ++i) {
      problem->SetParameterLowerBound(params, i, params[i] / options.max_focal_length_change);
      problem->SetParameterUpperBound(params, i, params[i] * options.max_focal_length_change);
    }
  }
  if (options.refine_principal_point) {
    const double size[2] = {double(camera->width), double(camera->height)};
    for (int axis = 0; axis < 2; ++axis) {
      // A start outside the bounds (a caller's camera) widens them: Ceres
      // needs a feasible start.
      const double pp = params[num_focal + axis];
      const double centre = (size[axis] - 1) / 2;
      const double reach = options.max_principal_point_offset * size[axis];
      problem->SetParameterLowerBound(params, num_focal + axis, std::min(pp, centre - reach));
      problem->SetParameterUpperBound(params, num_focal + axis, std::max(pp, centre + reach));
    }
  }
}

// Each camera in the problem: its readout time, and its intrinsics, constant
// or refined in part through a SubsetManifold, within their bounds.
void SetCameraBlocks(const FreeParameters& free_parameters,
                     const std::vector<char>& camera_added,
                     const BundleAdjuster::Options& options, BundleProblem* problem,
                     CeresProblem* ceres_problem) {
  for (int c = 0; c < static_cast<int>(problem->cameras.size()); ++c) {
    if (!camera_added[c]) continue;
    Camera& camera = problem->cameras[c];
    SetReadoutBlock(free_parameters.readout_free[c], options, &camera.readout_time,
                    ceres_problem);
    double* params = camera.params.data();
    ceres_problem->ordering->AddElementToGroup(params, 1);
    if (!free_parameters.camera_free[c]) {
      ceres_problem->problem.SetParameterBlockConstant(params);
      continue;
    }
    if (!free_parameters.constant_intrinsics[c].empty()) {
      ceres_problem->intrinsics_manifolds.push_back(std::make_unique<ceres::SubsetManifold>(
          camera.NumParams(), free_parameters.constant_intrinsics[c]));
      ceres_problem->problem.SetManifold(params,
                                         ceres_problem->intrinsics_manifolds.back().get());
    }
    BoundIntrinsics(options, &camera, &ceres_problem->problem);
  }
}

// The hierarchical weights: a prior on each refined pose with p > 1, from its
// information at the start (WeightedPoseInformation). Returns their number.
int AddPosePriors(const AddedResiduals& added, const std::vector<char>& point_free,
                  BundleProblem* problem, CeresProblem* ceres_problem) {
  const int num_images = static_cast<int>(problem->images.size());
  std::vector<char> weighted(num_images, 0);
  bool any_weighted = false;
  for (int i = 0; i < num_images; ++i) {
    weighted[i] = added.image_added[i] && problem->images[i].weight > 1.0;
    any_weighted = any_weighted || weighted[i];
  }
  if (!any_weighted) return 0;
  const std::vector<Matrix6d> information = WeightedPoseInformation(
      *problem, added.residuals, weighted, point_free, ceres_problem->loss.get());
  int num_priors = 0;
  for (int i = 0; i < num_images; ++i) {
    if (!weighted[i]) continue;
    Rigid3d& pose = problem->images[i].cam_from_world;
    ceres_problem->problem.AddResidualBlock(
        CreatePosePriorCost(pose, PriorSqrtInformation(information[i],
                                                       problem->images[i].weight)),
        nullptr, pose.rotation.coeffs().data(), pose.translation.data());
    ++num_priors;
  }
  return num_priors;
}

// The linear solver by the problem's size (Options, "Linear solver") and the
// options' limits.
ceres::Solver::Options MakeSolverOptions(
    const BundleAdjuster::Options& options, int num_free_images, int num_free_points,
    const BundleProblem& problem, const std::vector<AddedResidual>& residuals,
    const std::shared_ptr<ceres::ParameterBlockOrdering>& ordering) {
  ceres::Solver::Options solver_options;
  if (num_free_points == 0) {
    solver_options.linear_solver_type = num_free_images <= options.dense_schur_max_images
                                            ? ceres::DENSE_QR
                                            : ceres::SPARSE_NORMAL_CHOLESKY;
  } else {
    solver_options.linear_solver_ordering = ordering;
    if (WeightedMeanTrackLength(problem, residuals) > options.iterative_schur_min_track_length) {
      solver_options.linear_solver_type = ceres::ITERATIVE_SCHUR;
      solver_options.preconditioner_type = ceres::SCHUR_JACOBI;
    } else if (num_free_images <= options.dense_schur_max_images) {
      solver_options.linear_solver_type = ceres::DENSE_SCHUR;
    } else if (num_free_images <= options.sparse_schur_max_images) {
      solver_options.linear_solver_type = ceres::SPARSE_SCHUR;
    } else {
      solver_options.linear_solver_type = ceres::ITERATIVE_SCHUR;
      solver_options.preconditioner_type = ceres::SCHUR_JACOBI;
    }
  }
  solver_options.sparse_linear_algebra_library_type = ceres::SUITE_SPARSE;
  solver_options.max_num_iterations = options.max_num_iterations;
  solver_options.max_solver_time_in_seconds = options.max_solver_time_seconds;
  solver_options.function_tolerance = options.function_tolerance;
  solver_options.gradient_tolerance = options.gradient_tolerance;
  solver_options.parameter_tolerance = options.parameter_tolerance;
  solver_options.num_threads = options.num_threads;
  solver_options.logging_type = ceres::SILENT;
  solver_options.minimizer_progress_to_stdout = false;
  return solver_options;
}

// The solve's figures into `summary`, after the refined rotations are
// normalised again.
void ReadCeresSummary(const ceres::Solver::Summary& ceres_summary,
                      ceres::LinearSolverType linear_solver, const BundleProblem& problem,
                      const std::vector<AddedResidual>& residuals,
                      BundleAdjuster::Summary* summary) {
  summary->linear_solver = ceres::LinearSolverTypeToString(linear_solver);
  summary->initial_cost = ceres_summary.initial_cost;
  summary->final_cost = ceres_summary.final_cost;
  summary->final_mean_reprojection_error_px = MeanReprojectionError(problem, residuals);
  // Ceres lists the evaluation at the start as iteration 0.
  summary->num_iterations = std::max(0, static_cast<int>(ceres_summary.iterations.size()) - 1);
  summary->solver_time_seconds = ceres_summary.total_time_in_seconds;
  summary->termination = ToTermination(ceres_summary);
  summary->message = ceres_summary.message;
}

}  // namespace

bool BundleAdjuster::Options::Check() const {
  return loss_scale_px > 0 && iterative_schur_min_track_length > 0 &&
         dense_schur_max_images >= 0 &&
         sparse_schur_max_images >= dense_schur_max_images &&
         max_num_iterations > 0 && max_solver_time_seconds > 0 &&
         function_tolerance >= 0 && gradient_tolerance >= 0 &&
         parameter_tolerance >= 0 && num_threads >= 1 && max_focal_length_change > 1 &&
         max_principal_point_offset >= 0 && max_principal_point_offset < 0.5 &&
         max_readout_time_seconds > 0;
}

std::string BundleAdjuster::Summary::BriefReport() const {
  std::ostringstream out;
  out << "BA " << num_free_images << "/" << num_images << " images, "
      << num_free_points << "/" << num_points << " points, " << num_residuals
      << " residuals, " << num_pose_priors << " priors, " << linear_solver
      << ": cost " << initial_cost << " -> " << final_cost << ", error "
      << initial_mean_reprojection_error_px << " -> "
      << final_mean_reprojection_error_px << " px, " << num_iterations
      << " iterations, " << total_time_seconds << " s, "
      << TerminationName(termination);
  return out.str();
}

BundleAdjuster::BundleAdjuster(const Options& options) : options_(options) {
  FLYSFM_CHECK(options_.Check());
}

BundleAdjuster::Summary BundleAdjuster::Solve(BundleProblem* problem) const {
  const Clock::time_point start = Clock::now();
  FLYSFM_CHECK(problem != nullptr && problem->Check());
  const FreeParameters free_parameters = ChooseFreeParameters(*problem, options_);
  CeresProblem ceres_problem(options_);
  const AddedResiduals added =
      AddReprojectionResiduals(free_parameters, problem, &ceres_problem);

  Summary summary;
  summary.num_images = static_cast<int>(problem->images.size());
  summary.num_points = static_cast<int>(problem->points.size());
  summary.num_residuals = static_cast<int>(added.residuals.size());
  summary.initial_mean_reprojection_error_px =
      MeanReprojectionError(*problem, added.residuals);
  if (added.residuals.empty()) {
    summary.termination = Termination::kConvergence;
    summary.message = "nothing to refine";
    summary.final_mean_reprojection_error_px =
        summary.initial_mean_reprojection_error_px;
    summary.total_time_seconds = SecondsSince(start);
    return summary;
  }

  summary.num_free_images =
      SetPoseBlocks(added, free_parameters.gauge, problem, &ceres_problem);
  summary.num_free_points = SetPointBlocks(free_parameters, problem, &ceres_problem);
  SetCameraBlocks(free_parameters, added.camera_added, options_, problem, &ceres_problem);
  summary.num_pose_priors =
      AddPosePriors(added, free_parameters.point_free, problem, &ceres_problem);

  ceres::Solver::Options solver_options =
      MakeSolverOptions(options_, summary.num_free_images, summary.num_free_points,
                        *problem, added.residuals, ceres_problem.ordering);
  IterationCallback iteration_callback(options_);
  if (options_.should_stop || options_.on_iteration) {
    solver_options.callbacks.push_back(&iteration_callback);
  }
  ceres::Solver::Summary ceres_summary;
  ceres::Solve(solver_options, &ceres_problem.problem, &ceres_summary);

  // Ceres' steps keep a quaternion's norm only to rounding.
  for (int i = 0; i < summary.num_images; ++i) {
    if (added.image_added[i]) problem->images[i].cam_from_world.rotation.normalize();
  }
  ReadCeresSummary(ceres_summary, solver_options.linear_solver_type, *problem,
                   added.residuals, &summary);
  summary.total_time_seconds = SecondsSince(start);
  return summary;
}

}  // namespace flysfm
