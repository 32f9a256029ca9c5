#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "geometry/types.h"

namespace flysfm {

// A rigid transform x -> R x + t. Name instances by the frames they map, as
// `b_from_a`, so that composition reads right to left:
// cam2_from_cam1 = cam2_from_world * Inverse(cam1_from_world).
struct Rigid3d {
  Eigen::Quaterniond rotation = Eigen::Quaterniond::Identity();
  Eigen::Vector3d translation = Eigen::Vector3d::Zero();

  Rigid3d() = default;
  Rigid3d(const Eigen::Quaterniond& rotation, const Eigen::Vector3d& translation)
      : rotation(rotation.normalized()), translation(translation) {}
  Rigid3d(const Eigen::Matrix3d& rotation, const Eigen::Vector3d& translation)
      : rotation(Eigen::Quaterniond(rotation).normalized()),
        translation(translation) {}

  // [R | t].
  Matrix3x4d ToMatrix() const;
};

Rigid3d Inverse(const Rigid3d& b_from_a);

inline Eigen::Vector3d operator*(const Rigid3d& b_from_a,
                                 const Eigen::Vector3d& x_in_a) {
  return b_from_a.rotation * x_in_a + b_from_a.translation;
}

// c_from_a = c_from_b * b_from_a.
Rigid3d operator*(const Rigid3d& c_from_b, const Rigid3d& b_from_a);

// Angle of the relative rotation between two transforms, in degrees.
double RotationDifferenceDeg(const Rigid3d& a, const Rigid3d& b);

// Camera centre in world coordinates of a cam_from_world pose.
Eigen::Vector3d ProjectionCenter(const Rigid3d& cam_from_world);

}  // namespace flysfm
