#pragma once

// Homography solver: x2 ~ H x1 for a point x1 in image 1 and its match x2 in
// image 2 (homogeneous, w = 1).

#include <limits>
#include <vector>

#include <Eigen/Core>

namespace flysfm {

// The normalized direct linear transform (n >= 4 matches, least squares for
// n > 4). At most one solution, scaled to unit Frobenius norm; none for
// degenerate input (too few or unequal numbers of points, non-finite values,
// three or more collinear points in a minimal sample, repeated points) or a
// singular result.
std::vector<Eigen::Matrix3d> HomographyFromPoints(
    const std::vector<Eigen::Vector2d>& points1,
    const std::vector<Eigen::Vector2d>& points2);

// Squared Sampson distance of a match to the homography: the first-order
// approximation of the squared distance, in the 4D space of (x1, x2), to the
// nearest pair with x2 = H x1 exactly. Units of the points. Comparable with
// FundamentalSampsonError (same space), which GRIC relies on.
inline double HomographySampsonError(const Eigen::Matrix3d& H,
                                     const Eigen::Vector2d& x1,
                                     const Eigen::Vector2d& x2) {
  const double a = H(0, 0) * x1.x() + H(0, 1) * x1.y() + H(0, 2);
  const double b = H(1, 0) * x1.x() + H(1, 1) * x1.y() + H(1, 2);
  const double c = H(2, 0) * x1.x() + H(2, 1) * x1.y() + H(2, 2);
  // Algebraic errors: the first two rows of x2 x (H x1).
  const double e1 = x2.y() * c - b;
  const double e2 = a - x2.x() * c;
  // Their Jacobian with respect to (x1, y1, x2, y2).
  const double j11 = x2.y() * H(2, 0) - H(1, 0);
  const double j12 = x2.y() * H(2, 1) - H(1, 1);
  const double j21 = H(0, 0) - x2.x() * H(2, 0);
  const double j22 = H(0, 1) - x2.x() * H(2, 1);
  // J J^T with J = [[j11, j12, 0, c], [j21, j22, -c, 0]].
  const double s11 = j11 * j11 + j12 * j12 + c * c;
  const double s12 = j11 * j21 + j12 * j22;
  const double s22 = j21 * j21 + j22 * j22 + c * c;
  const double det = s11 * s22 - s12 * s12;
  if (!(det > 0)) return std::numeric_limits<double>::infinity();
  return (s22 * e1 * e1 - 2 * s12 * e1 * e2 + s11 * e2 * e2) / det;
}

// Squared distance in image 2 between x2 and H x1.
double HomographyTransferError(const Eigen::Matrix3d& H,
                               const Eigen::Vector2d& x1,
                               const Eigen::Vector2d& x2);

}  // namespace flysfm
