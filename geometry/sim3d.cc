#include "geometry/sim3d.h"

namespace flysfm {

Matrix3x4d Sim3d::ToMatrix() const {
  Matrix3x4d matrix;
  matrix.leftCols<3>() = scale * rotation.toRotationMatrix();
  matrix.col(3) = translation;
  return matrix;
}

Sim3d Inverse(const Sim3d& b_from_a) {
  const double inv_scale = 1.0 / b_from_a.scale;
  const Eigen::Quaterniond inv_rotation = b_from_a.rotation.inverse();
  return Sim3d(inv_scale, inv_rotation,
               -inv_scale * (inv_rotation * b_from_a.translation));
}

Sim3d operator*(const Sim3d& c_from_b, const Sim3d& b_from_a) {
  return Sim3d(c_from_b.scale * b_from_a.scale,
               c_from_b.rotation * b_from_a.rotation,
               c_from_b * b_from_a.translation);
}

Rigid3d TransformPose(const Sim3d& new_from_old, const Rigid3d& cam_from_old) {
  // cam(x) = s * cam_from_old(old_from_new(x)), rescaled to stay rigid.
  const Eigen::Quaterniond rotation =
      cam_from_old.rotation * new_from_old.rotation.inverse();
  return Rigid3d(rotation, new_from_old.scale * cam_from_old.translation -
                               rotation * new_from_old.translation);
}

}  // namespace flysfm
