#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "geometry/rigid3d.h"

namespace flysfm {

// A similarity x -> s R x + t, e.g. `gt_from_model` after aligning a
// reconstruction (known only up to scale) to ground truth.
struct Sim3d {
  double scale = 1.0;
  Eigen::Quaterniond rotation = Eigen::Quaterniond::Identity();
  Eigen::Vector3d translation = Eigen::Vector3d::Zero();

  Sim3d() = default;
  Sim3d(double scale, const Eigen::Quaterniond& rotation,
        const Eigen::Vector3d& translation)
      : scale(scale), rotation(rotation.normalized()), translation(translation) {}

  // [sR | t].
  Matrix3x4d ToMatrix() const;
};

Sim3d Inverse(const Sim3d& b_from_a);

inline Eigen::Vector3d operator*(const Sim3d& b_from_a,
                                 const Eigen::Vector3d& x_in_a) {
  return b_from_a.scale * (b_from_a.rotation * x_in_a) + b_from_a.translation;
}

Sim3d operator*(const Sim3d& c_from_b, const Sim3d& b_from_a);

// The pose of a camera after its world is mapped by new_from_old:
// cam_from_new maps the new world into the camera, metric in the new scale.
Rigid3d TransformPose(const Sim3d& new_from_old, const Rigid3d& cam_from_old);

}  // namespace flysfm
