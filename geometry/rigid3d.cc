#include "geometry/rigid3d.h"

#include <algorithm>
#include <cmath>

namespace flysfm {

Matrix3x4d Rigid3d::ToMatrix() const {
  Matrix3x4d matrix;
  matrix.leftCols<3>() = rotation.toRotationMatrix();
  matrix.col(3) = translation;
  return matrix;
}

Rigid3d Inverse(const Rigid3d& b_from_a) {
  const Eigen::Quaterniond a_from_b_rotation = b_from_a.rotation.inverse();
  return Rigid3d(a_from_b_rotation, -(a_from_b_rotation * b_from_a.translation));
}

Rigid3d operator*(const Rigid3d& c_from_b, const Rigid3d& b_from_a) {
  return Rigid3d(c_from_b.rotation * b_from_a.rotation,
                 c_from_b.rotation * b_from_a.translation + c_from_b.translation);
}

double RotationDifferenceDeg(const Rigid3d& a, const Rigid3d& b) {
  return a.rotation.angularDistance(b.rotation) * 180.0 / M_PI;
}

Eigen::Vector3d ProjectionCenter(const Rigid3d& cam_from_world) {
  return -(cam_from_world.rotation.inverse() * cam_from_world.translation);
}

}  // namespace flysfm
