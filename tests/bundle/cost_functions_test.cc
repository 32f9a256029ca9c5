#include "bundle/cost_functions.h"

#include <memory>
#include <random>
#include <string>
#include <vector>

// Ceres pulls in glog, whose CHECK would silently replace Catch's: include it
// first and drop glog's macro before Catch defines its own.
#include <ceres/ceres.h>
#undef CHECK
#include <catch2/catch.hpp>

#include "geometry/camera.h"
#include "tests/testing/synthetic.h"

namespace flysfm {
namespace {

using RowMatrixXd = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

// Residual of the cost at a pose moved by `delta` (6: rotation tangent of
// EigenQuaternionManifold, translation), a point moved by `point_delta` and
// camera params moved by `param_delta`.
Eigen::Vector2d ResidualAt(const ceres::CostFunction& cost, const Rigid3d& pose,
                           const Eigen::Vector3d& point,
                           const std::vector<double>& params,
                           const Eigen::VectorXd& delta) {
  Eigen::Quaterniond rotation;
  ceres::EigenQuaternionManifold().Plus(pose.rotation.coeffs().data(), delta.data(),
                                        rotation.coeffs().data());
  Eigen::Vector3d translation = pose.translation + delta.segment<3>(3);
  Eigen::Vector3d moved_point = point + delta.segment<3>(6);
  std::vector<double> moved_params = params;
  for (size_t i = 0; i < params.size(); ++i) moved_params[i] += delta[9 + i];
  const double* blocks[] = {rotation.coeffs().data(), translation.data(),
                            moved_point.data(), moved_params.data()};
  Eigen::Vector2d residual;
  REQUIRE(cost.Evaluate(blocks, residual.data(), nullptr));
  return residual;
}

TEST_CASE("Reprojection costs match the camera models and their derivatives") {
  const std::vector<std::string> models = {
      "SIMPLE_PINHOLE 500,320,240",
      "PINHOLE 500,505,320,240",
      "SIMPLE_RADIAL 500,320,240,-0.05",
      "RADIAL 500,320,240,-0.05,0.01",
      "OPENCV 500,505,320,240,-0.05,0.01,0.001,-0.001",
      "FULL_OPENCV 500,505,320,240,-0.05,0.01,0.001,-0.001,0.001,0.01,0,0"};
  std::mt19937 rng(3);
  for (const std::string& model : models) {
    INFO(model);
    const Camera camera = Camera::FromString(model, 640, 480);
    const int num_params = camera.NumParams();
    const Rigid3d pose(testing::RandomRotation(rng), Eigen::Vector3d(0.1, -0.2, 4));
    const Eigen::Vector3d point =
        Inverse(pose) * (Eigen::Vector3d(0.3, -0.2, 1.0) * 2.5);
    const Eigen::Vector2d pixel(300, 200);
    const std::unique_ptr<ceres::CostFunction> cost(
        CreateReprojectionCost(camera.model_id, pixel));
    const std::unique_ptr<ceres::CostFunction> constant_pose_cost(
        CreateConstantPoseReprojectionCost(camera.model_id, pose, pixel));

    Eigen::Quaterniond rotation = pose.rotation;
    Eigen::Vector3d translation = pose.translation;
    Eigen::Vector3d x = point;
    std::vector<double> params = camera.params;
    const double* blocks[] = {rotation.coeffs().data(), translation.data(),
                              x.data(), params.data()};
    Eigen::Vector2d residual;
    RowMatrixXd j_rotation(2, 4), j_translation(2, 3), j_point(2, 3),
        j_params(2, num_params);
    double* jacobians[] = {j_rotation.data(), j_translation.data(), j_point.data(),
                           j_params.data()};
    REQUIRE(cost->Evaluate(blocks, residual.data(), jacobians));
    const Eigen::Vector2d expected = camera.ImgFromCam(pose * point) - pixel;
    CHECK((residual - expected).norm() < 1e-9);

    // Tangent-space Jacobian, as Ceres forms it: ambient times PlusJacobian.
    RowMatrixXd plus(4, 3);
    ceres::EigenQuaternionManifold().PlusJacobian(blocks[0], plus.data());
    RowMatrixXd analytic(2, 9 + num_params);
    analytic << j_rotation * plus, j_translation, j_point, j_params;

    const int n = 9 + num_params;
    for (int k = 0; k < n; ++k) {
      const double h = k < 3 ? 1e-6 : k < 9 ? 1e-6 : 1e-6 * std::max(1.0, std::abs(params[k - 9]));
      Eigen::VectorXd delta = Eigen::VectorXd::Zero(n);
      delta[k] = h;
      const Eigen::Vector2d plus_h = ResidualAt(*cost, pose, point, camera.params, delta);
      delta[k] = -h;
      const Eigen::Vector2d minus_h = ResidualAt(*cost, pose, point, camera.params, delta);
      const Eigen::Vector2d numeric = (plus_h - minus_h) / (2 * h);
      INFO("parameter " << k << ": analytic " << analytic.col(k).transpose()
                        << ", numeric " << numeric.transpose());
      CHECK((analytic.col(k) - numeric).norm() <
            1e-5 * std::max(1.0, numeric.norm()));
    }

    // The constant-pose cost: same residual and point/params derivatives.
    Eigen::Vector2d constant_residual;
    RowMatrixXd c_point(2, 3), c_params(2, num_params);
    const double* constant_blocks[] = {x.data(), params.data()};
    double* constant_jacobians[] = {c_point.data(), c_params.data()};
    REQUIRE(constant_pose_cost->Evaluate(constant_blocks, constant_residual.data(),
                                         constant_jacobians));
    CHECK((constant_residual - residual).norm() < 1e-9);
    CHECK((c_point - j_point).norm() < 1e-9 * j_point.norm());
    CHECK((c_params - j_params).norm() < 1e-9 * j_params.norm());
  }
}

TEST_CASE("The rolling-shutter cost moves the point along the motion by its row's time") {
  std::mt19937 rng(5);
  for (const std::string model :
       {"PINHOLE 500,505,320,240",
        "FULL_OPENCV 500,505,320,240,-0.05,0.01,0.001,-0.001,0.001,0.01,0,0"}) {
    INFO(model);
    const Camera camera = Camera::FromString(model, 640, 480);
    const int num_params = camera.NumParams();
    const Rigid3d pose(testing::RandomRotation(rng), Eigen::Vector3d(0.1, -0.2, 4));
    const Eigen::Vector3d point = Inverse(pose) * (Eigen::Vector3d(0.3, -0.2, 1.0) * 2.5);
    // A hand-held camera: 0.5 rad/s and 0.3 m/s, read out in 30 ms.
    const Eigen::Vector3d angular(0.3, -0.4, 0.1), linear(0.2, 0.1, -0.2);
    const Eigen::Vector2d pixel(300, 400);
    const double fraction = RowTimeFraction(pixel.y(), camera.height);
    const std::unique_ptr<ceres::CostFunction> cost(CreateRollingShutterReprojectionCost(
        camera.model_id, pixel, fraction, angular, linear));
    const std::unique_ptr<ceres::CostFunction> still(
        CreateReprojectionCost(camera.model_id, pixel));

    const auto residual_at = [&](const Eigen::VectorXd& delta, RowMatrixXd* jacobian) {
      Eigen::Quaterniond rotation;
      ceres::EigenQuaternionManifold().Plus(pose.rotation.coeffs().data(), delta.data(),
                                            rotation.coeffs().data());
      const Eigen::Vector3d translation = pose.translation + delta.segment<3>(3);
      const Eigen::Vector3d moved_point = point + delta.segment<3>(6);
      std::vector<double> params = camera.params;
      for (int i = 0; i < num_params; ++i) params[i] += delta[9 + i];
      const double readout = 0.03 + delta[9 + num_params];
      const double* blocks[] = {rotation.coeffs().data(), translation.data(),
                                moved_point.data(), params.data(), &readout};
      Eigen::Vector2d residual;
      if (jacobian == nullptr) {
        REQUIRE(cost->Evaluate(blocks, residual.data(), nullptr));
        return residual;
      }
      RowMatrixXd j_rotation(2, 4), j_translation(2, 3), j_point(2, 3),
          j_params(2, num_params), j_readout(2, 1);
      double* jacobians[] = {j_rotation.data(), j_translation.data(), j_point.data(),
                             j_params.data(), j_readout.data()};
      REQUIRE(cost->Evaluate(blocks, residual.data(), jacobians));
      RowMatrixXd plus(4, 3);
      ceres::EigenQuaternionManifold().PlusJacobian(blocks[0], plus.data());
      jacobian->resize(2, 10 + num_params);
      *jacobian << j_rotation * plus, j_translation, j_point, j_params, j_readout;
      return residual;
    };

    const int n = 10 + num_params;
    RowMatrixXd analytic;
    const Eigen::Vector2d residual = residual_at(Eigen::VectorXd::Zero(n), &analytic);
    const Eigen::Vector3d in_cam = pose * point;
    const double tau = fraction * 0.03;
    const Eigen::Vector2d expected =
        camera.ImgFromCam(in_cam + tau * (angular.cross(in_cam) + linear)) - pixel;
    CHECK((residual - expected).norm() < 1e-9);
    // The motion moves the point by about 0.5 px here: enough to matter.
    Eigen::Vector2d still_residual;
    const double* still_blocks[] = {pose.rotation.coeffs().data(), pose.translation.data(),
                                    point.data(), camera.params.data()};
    REQUIRE(still->Evaluate(still_blocks, still_residual.data(), nullptr));
    CHECK((still_residual - residual).norm() > 0.1);

    // Pose and readout time held: the folded constant-pose cost gives the
    // same residual and point and camera derivatives.
    const std::unique_ptr<ceres::CostFunction> held(CreateConstantPoseReprojectionCost(
        camera.model_id, pose, pixel, tau, angular, linear));
    Eigen::Vector2d held_residual;
    RowMatrixXd h_point(2, 3), h_params(2, num_params);
    const double* held_blocks[] = {point.data(), camera.params.data()};
    double* held_jacobians[] = {h_point.data(), h_params.data()};
    REQUIRE(held->Evaluate(held_blocks, held_residual.data(), held_jacobians));
    CHECK((held_residual - residual).norm() < 1e-9);
    CHECK((h_point - analytic.middleCols(6, 3)).norm() < 1e-9 * h_point.norm());
    CHECK((h_params - analytic.middleCols(9, num_params)).norm() < 1e-9 * h_params.norm());

    for (int k = 0; k < n; ++k) {
      const double h = k < 9 || k == n - 1 ? 1e-6 : 1e-6 * std::max(1.0, std::abs(camera.params[k - 9]));
      Eigen::VectorXd delta = Eigen::VectorXd::Zero(n);
      delta[k] = h;
      const Eigen::Vector2d plus_h = residual_at(delta, nullptr);
      delta[k] = -h;
      const Eigen::Vector2d minus_h = residual_at(delta, nullptr);
      const Eigen::Vector2d numeric = (plus_h - minus_h) / (2 * h);
      INFO("parameter " << k << ": analytic " << analytic.col(k).transpose()
                        << ", numeric " << numeric.transpose());
      CHECK((analytic.col(k) - numeric).norm() < 1e-5 * std::max(1.0, numeric.norm()));
    }
  }
}

TEST_CASE("The pose prior is zero at the prior and L times the tangent near it") {
  std::mt19937 rng(4);
  const Rigid3d prior(testing::RandomRotation(rng), Eigen::Vector3d(1, 2, 3));
  const Matrix6d a = Matrix6d::Random();
  const Matrix6d sqrt_information = a.transpose() * a;
  const std::unique_ptr<ceres::CostFunction> cost(
      CreatePosePriorCost(prior, sqrt_information));

  Eigen::Matrix<double, 6, 1> delta;
  delta << 1e-3, -2e-3, 0.5e-3, 0.01, -0.02, 0.03;
  Eigen::Quaterniond rotation;
  ceres::EigenQuaternionManifold().Plus(prior.rotation.coeffs().data(), delta.data(),
                                        rotation.coeffs().data());
  Eigen::Vector3d translation = prior.translation + delta.tail<3>();
  Eigen::Matrix<double, 6, 1> residual;
  const double* blocks[] = {rotation.coeffs().data(), translation.data()};
  REQUIRE(cost->Evaluate(blocks, residual.data(), nullptr));
  // Exact: the tangent of EigenQuaternionManifold is half the rotation vector.
  CHECK((residual - sqrt_information * delta).norm() <
        1e-9 * (sqrt_information * delta).norm());

  const double* at_prior[] = {prior.rotation.coeffs().data(),
                              prior.translation.data()};
  REQUIRE(cost->Evaluate(at_prior, residual.data(), nullptr));
  CHECK(residual.norm() < 1e-12);
}

}  // namespace
}  // namespace flysfm
