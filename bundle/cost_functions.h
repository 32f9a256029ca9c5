#pragma once

// Ceres cost functions of the bundle module. A pose is two parameter blocks:
// the cam_from_world rotation as an Eigen quaternion (x, y, z, w in memory,
// on ceres::EigenQuaternionManifold) and the translation. All camera models
// share one templated reprojection cost: the rigid part is differentiated in
// closed form, the model's projection automatically (docs/bundle.md).

#include <Eigen/Core>

#include "geometry/camera_models.h"
#include "geometry/rigid3d.h"

namespace ceres {
class CostFunction;
}

namespace flysfm {

using Matrix6d = Eigen::Matrix<double, 6, 6>;

// Residual: projected minus observed pixel. Parameter blocks: rotation (4),
// translation (3), point (3), camera params (the model's count).
ceres::CostFunction* CreateReprojectionCost(CameraModelId model_id,
                                            const Eigen::Vector2d& pixel);

// The same residual for a rolling-shutter image (bundle_problem.h,
// BundleImage::IsMoving): the point moves by its row's time, the fraction
// RowTimeFraction of the camera's readout time, along the image's motion.
// Parameter blocks: rotation (4), translation (3), point (3), camera params,
// readout time (1).
ceres::CostFunction* CreateRollingShutterReprojectionCost(
    CameraModelId model_id, const Eigen::Vector2d& pixel,
    double row_time_fraction, const Eigen::Vector3d& angular_velocity,
    const Eigen::Vector3d& linear_velocity);

// The same residual for an image whose pose is held constant, the pose folded
// into the cost. Parameter blocks: point (3), camera params. For a
// rolling-shutter image whose readout time is held too, `row_time` (seconds:
// RowTimeFraction times the readout time) and the image's motion fold in
// as well, the rolling-shutter cost with its pose and readout held.
ceres::CostFunction* CreateConstantPoseReprojectionCost(
    CameraModelId model_id, const Rigid3d& cam_from_world,
    const Eigen::Vector2d& pixel, double row_time = 0,
    const Eigen::Vector3d& angular_velocity = Eigen::Vector3d::Zero(),
    const Eigen::Vector3d& linear_velocity = Eigen::Vector3d::Zero());

// Residual: sqrt_information * e, e = (rotation error, t - t_prior), where the
// rotation error is the tangent of ceres::EigenQuaternionManifold at the
// prior, i.e. half the rotation vector of R R_prior^T. Parameter blocks:
// rotation (4), translation (3).
ceres::CostFunction* CreatePosePriorCost(const Rigid3d& prior_cam_from_world,
                                         const Matrix6d& sqrt_information);

}  // namespace flysfm
