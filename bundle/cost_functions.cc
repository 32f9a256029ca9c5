#include "bundle/cost_functions.h"

#include <ceres/autodiff_cost_function.h>
#include <ceres/jet.h>
#include <ceres/manifold.h>
#include <ceres/rotation.h>
#include <ceres/sized_cost_function.h>

#include <Eigen/Geometry>

namespace flysfm {
namespace {

// Projection of a camera-frame point and its derivatives with respect to that
// point and, when asked, the camera parameters: automatic differentiation of
// the model's templated ImgFromCam on small Jets, so every model shares it.
// Held intrinsics (the usual case) need Jets of 3 only: for FULL_OPENCV that
// is a fifth of the work of 3 + 12.
template <typename Model>
struct Projection {
  static constexpr int kNumParams = Model::kNumParams;
  Eigen::Vector2d pixel;
  Eigen::Matrix<double, 2, 3, Eigen::RowMajor> d_point;
  Eigen::Matrix<double, 2, kNumParams, Eigen::RowMajor> d_params;

  void Evaluate(const double* params, const Eigen::Vector3d& in_cam,
                bool derivatives, bool param_derivatives) {
    if (!derivatives) {
      Model::ImgFromCam(params, in_cam.x(), in_cam.y(), in_cam.z(), &pixel.x(),
                        &pixel.y());
    } else if (param_derivatives) {
      Differentiate<3 + kNumParams>(params, in_cam);
    } else {
      Differentiate<3>(params, in_cam);
    }
  }

 private:
  template <int kNumDerivatives>
  void Differentiate(const double* params, const Eigen::Vector3d& in_cam) {
    using Jet = ceres::Jet<double, kNumDerivatives>;
    Jet jet_params[kNumParams];
    for (int i = 0; i < kNumParams; ++i) {
      if constexpr (kNumDerivatives > 3) {
        jet_params[i] = Jet(params[i], 3 + i);
      } else {
        jet_params[i] = Jet(params[i]);
      }
    }
    Jet x, y;
    Model::ImgFromCam(jet_params, Jet(in_cam.x(), 0), Jet(in_cam.y(), 1),
                      Jet(in_cam.z(), 2), &x, &y);
    pixel = Eigen::Vector2d(x.a, y.a);
    d_point.row(0) = x.v.template head<3>();
    d_point.row(1) = y.v.template head<3>();
    if constexpr (kNumDerivatives > 3) {
      d_params.row(0) = x.v.template tail<kNumParams>();
      d_params.row(1) = y.v.template tail<kNumParams>();
    }
  }
};

// Writes the derivatives of the residual with respect to a point that enters
// the camera frame as R X, and to the camera parameters.
template <typename Model>
void PointAndParamJacobians(const Projection<Model>& projection,
                            const Eigen::Matrix3d& rotation, double* d_point,
                            double* d_params) {
  if (d_point != nullptr) {
    Eigen::Map<Eigen::Matrix<double, 2, 3, Eigen::RowMajor>> jacobian(d_point);
    jacobian = projection.d_point * rotation;
  }
  if (d_params != nullptr) {
    Eigen::Map<Eigen::Matrix<double, 2, Model::kNumParams, Eigen::RowMajor>>
        jacobian(d_params);
    jacobian = projection.d_params;
  }
}

// A point block in the frame of a pose's two blocks: R, R X and R X + t.
struct PosedPoint {
  PosedPoint(const double* quaternion, const double* translation, const double* point)
      : rotation(Eigen::Map<const Eigen::Quaterniond>(quaternion).toRotationMatrix()),
        rotated(rotation * Eigen::Map<const Eigen::Vector3d>(point)),
        in_cam(rotated + Eigen::Map<const Eigen::Vector3d>(translation)) {}
  Eigen::Matrix3d rotation;
  Eigen::Vector3d rotated;
  Eigen::Vector3d in_cam;
};

// Writes the derivatives of the residual with respect to the rotation and the
// translation, given its derivative with respect to the point in the camera
// frame, d_in_cam, and R X (`rotated`).
void PoseJacobians(const Eigen::Matrix<double, 2, 3, Eigen::RowMajor>& d_in_cam,
                   const double* quaternion, const Eigen::Vector3d& rotated,
                   double* d_rotation, double* d_translation) {
  if (d_rotation != nullptr) {
    Eigen::Matrix3d minus_2_skew;
    minus_2_skew << 0, 2 * rotated.z(), -2 * rotated.y(),  //
        -2 * rotated.z(), 0, 2 * rotated.x(),              //
        2 * rotated.y(), -2 * rotated.x(), 0;
    Eigen::Matrix<double, 4, 3, Eigen::RowMajor> plus_jacobian;
    ceres::EigenQuaternionManifold().PlusJacobian(quaternion,
                                                  plus_jacobian.data());
    Eigen::Map<Eigen::Matrix<double, 2, 4, Eigen::RowMajor>> jacobian(d_rotation);
    jacobian = d_in_cam * minus_2_skew * plus_jacobian.transpose();
  }
  if (d_translation != nullptr) {
    Eigen::Map<Eigen::Matrix<double, 2, 3, Eigen::RowMajor>> jacobian(d_translation);
    jacobian = d_in_cam;
  }
}

// Residual and Jacobians in closed form for the pose and point, the model's
// projection differentiated automatically (Projection above): about three
// times faster than differentiating the whole chain with Jets of 10 + #params.
//
// The rotation Jacobian: EigenQuaternionManifold moves q to Exp(d) q, a
// rotation by 2d, so the tangent Jacobian of R X is -2 [R X]x. Ceres wants the
// Jacobian in the ambient quaternion coordinates and multiplies it by the
// manifold's PlusJacobian P (4x3, orthonormal columns for a unit q); passing
// J_tangent P^T gives back exactly J_tangent.
template <typename Model>
class ReprojectionCost
    : public ceres::SizedCostFunction<2, 4, 3, 3, Model::kNumParams> {
 public:
  explicit ReprojectionCost(const Eigen::Vector2d& pixel) : pixel_(pixel) {}

  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override {
    const PosedPoint posed(parameters[0], parameters[1], parameters[2]);
    Projection<Model> projection;
    projection.Evaluate(parameters[3], posed.in_cam, jacobians != nullptr,
                        jacobians != nullptr && jacobians[3] != nullptr);
    residuals[0] = projection.pixel.x() - pixel_.x();
    residuals[1] = projection.pixel.y() - pixel_.y();
    if (jacobians == nullptr) return true;
    PoseJacobians(projection.d_point, parameters[0], posed.rotated, jacobians[0],
                  jacobians[1]);
    PointAndParamJacobians(projection, posed.rotation, jacobians[2], jacobians[3]);
    return true;
  }

 private:
  Eigen::Vector2d pixel_;
};

// I + tau [w]x: the linear part of a rolling-shutter row's motion, a point p
// of the pose's frame moving to p + tau (w x p + v).
Eigen::Matrix3d MovedFromCam(double tau, const Eigen::Vector3d& angular_velocity) {
  Eigen::Matrix3d skew;
  skew << 0, -angular_velocity.z(), angular_velocity.y(),  //
      angular_velocity.z(), 0, -angular_velocity.x(),      //
      -angular_velocity.y(), angular_velocity.x(), 0;
  return Eigen::Matrix3d::Identity() + tau * skew;
}

// ReprojectionCost for a rolling-shutter image (BundleImage::IsMoving): the
// point in the pose's frame, p, is moved to where it is when its row is read,
// p + tau (w x p + v) with tau = row fraction * readout time, a fifth
// parameter block. The chain is the rigid one with d(moved)/dp = I + tau [w]x
// in front.
template <typename Model>
class RollingShutterReprojectionCost
    : public ceres::SizedCostFunction<2, 4, 3, 3, Model::kNumParams, 1> {
 public:
  RollingShutterReprojectionCost(const Eigen::Vector2d& pixel,
                                 double row_time_fraction,
                                 const Eigen::Vector3d& angular_velocity,
                                 const Eigen::Vector3d& linear_velocity)
      : pixel_(pixel),
        row_time_fraction_(row_time_fraction),
        angular_velocity_(angular_velocity),
        linear_velocity_(linear_velocity) {}

  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override {
    const PosedPoint posed(parameters[0], parameters[1], parameters[2]);
    const double tau = row_time_fraction_ * parameters[4][0];
    const Eigen::Vector3d motion =
        angular_velocity_.cross(posed.in_cam) + linear_velocity_;
    Projection<Model> projection;
    projection.Evaluate(parameters[3], posed.in_cam + tau * motion,
                        jacobians != nullptr,
                        jacobians != nullptr && jacobians[3] != nullptr);
    residuals[0] = projection.pixel.x() - pixel_.x();
    residuals[1] = projection.pixel.y() - pixel_.y();
    if (jacobians == nullptr) return true;
    const Eigen::Matrix3d d_moved = MovedFromCam(tau, angular_velocity_);
    const Eigen::Matrix<double, 2, 3, Eigen::RowMajor> d_in_cam =
        projection.d_point * d_moved;
    PoseJacobians(d_in_cam, parameters[0], posed.rotated, jacobians[0], jacobians[1]);
    // The point enters the projection as d_moved R X.
    PointAndParamJacobians(projection, d_moved * posed.rotation, jacobians[2],
                           jacobians[3]);
    if (jacobians[4] != nullptr) {
      Eigen::Map<Eigen::Vector2d> d_readout(jacobians[4]);
      d_readout = projection.d_point * (row_time_fraction_ * motion);
    }
    return true;
  }

 private:
  Eigen::Vector2d pixel_;
  double row_time_fraction_;
  Eigen::Vector3d angular_velocity_;
  Eigen::Vector3d linear_velocity_;
};

// ReprojectionCost for a held pose, folded into the cost: the point enters
// the projection as A X + b, a rigid cam_from_world or, for a rolling-shutter
// image whose readout time is held as well, that pose followed by the row's
// motion (I + tau [w]x) p + tau v, affine in X too.
template <typename Model>
class ConstantPoseReprojectionCost
    : public ceres::SizedCostFunction<2, 3, Model::kNumParams> {
 public:
  ConstantPoseReprojectionCost(const Eigen::Matrix3d& linear,
                               const Eigen::Vector3d& offset,
                               const Eigen::Vector2d& pixel)
      : linear_(linear), offset_(offset), pixel_(pixel) {}

  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override {
    const Eigen::Vector3d in_cam =
        linear_ * Eigen::Map<const Eigen::Vector3d>(parameters[0]) + offset_;
    Projection<Model> projection;
    projection.Evaluate(parameters[1], in_cam, jacobians != nullptr,
                        jacobians != nullptr && jacobians[1] != nullptr);
    residuals[0] = projection.pixel.x() - pixel_.x();
    residuals[1] = projection.pixel.y() - pixel_.y();
    if (jacobians != nullptr) {
      PointAndParamJacobians(projection, linear_, jacobians[0], jacobians[1]);
    }
    return true;
  }

 private:
  Eigen::Matrix3d linear_;
  Eigen::Vector3d offset_;
  Eigen::Vector2d pixel_;
};

struct PosePriorCost {
  PosePriorCost(const Rigid3d& prior, const Matrix6d& sqrt_information)
      : prior_rotation_inverse(prior.rotation.conjugate()),
        prior_translation(prior.translation),
        sqrt_information(sqrt_information) {}

  template <typename T>
  bool operator()(const T* rotation, const T* translation, T* residuals) const {
    const Eigen::Map<const Eigen::Quaternion<T>> q(rotation);
    const Eigen::Quaternion<T> delta = q * prior_rotation_inverse.cast<T>();
    const T delta_wxyz[4] = {delta.w(), delta.x(), delta.y(), delta.z()};
    T rotation_vector[3];
    ceres::QuaternionToAngleAxis(delta_wxyz, rotation_vector);
    Eigen::Matrix<T, 6, 1> error;
    for (int i = 0; i < 3; ++i) {
      error[i] = T(0.5) * rotation_vector[i];
      error[3 + i] = translation[i] - T(prior_translation[i]);
    }
    Eigen::Map<Eigen::Matrix<T, 6, 1>> weighted_error(residuals);
    weighted_error = sqrt_information.cast<T>() * error;
    return true;
  }

  Eigen::Quaterniond prior_rotation_inverse;
  Eigen::Vector3d prior_translation;
  Matrix6d sqrt_information;
};

}  // namespace

ceres::CostFunction* CreateReprojectionCost(CameraModelId model_id,
                                            const Eigen::Vector2d& pixel) {
  return VisitCameraModel(model_id, [&](auto model) -> ceres::CostFunction* {
    using Model = decltype(model);
    return new ReprojectionCost<Model>(pixel);
  });
}

ceres::CostFunction* CreateRollingShutterReprojectionCost(
    CameraModelId model_id, const Eigen::Vector2d& pixel,
    double row_time_fraction, const Eigen::Vector3d& angular_velocity,
    const Eigen::Vector3d& linear_velocity) {
  return VisitCameraModel(model_id, [&](auto model) -> ceres::CostFunction* {
    using Model = decltype(model);
    return new RollingShutterReprojectionCost<Model>(
        pixel, row_time_fraction, angular_velocity, linear_velocity);
  });
}

ceres::CostFunction* CreateConstantPoseReprojectionCost(
    CameraModelId model_id, const Rigid3d& cam_from_world,
    const Eigen::Vector2d& pixel, double row_time,
    const Eigen::Vector3d& angular_velocity, const Eigen::Vector3d& linear_velocity) {
  const Eigen::Matrix3d moved_from_cam = MovedFromCam(row_time, angular_velocity);
  const Eigen::Matrix3d linear =
      moved_from_cam * cam_from_world.rotation.toRotationMatrix();
  const Eigen::Vector3d offset =
      moved_from_cam * cam_from_world.translation + row_time * linear_velocity;
  return VisitCameraModel(model_id, [&](auto model) -> ceres::CostFunction* {
    using Model = decltype(model);
    return new ConstantPoseReprojectionCost<Model>(linear, offset, pixel);
  });
}

ceres::CostFunction* CreatePosePriorCost(const Rigid3d& prior_cam_from_world,
                                         const Matrix6d& sqrt_information) {
  return new ceres::AutoDiffCostFunction<PosePriorCost, 6, 4, 3>(
      new PosePriorCost(prior_cam_from_world, sqrt_information));
}

}  // namespace flysfm
