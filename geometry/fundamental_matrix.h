#pragma once

// Fundamental matrix solvers: x2^T F x1 = 0 for a point x1 in image 1 and its
// match x2 in image 2 (pixels, homogeneous with w = 1). Every solver works on
// Hartley-normalized points, returns matrices scaled to unit Frobenius norm,
// and returns no solution for degenerate input: too few or unequal numbers of
// points, non-finite values, or a configuration (collinear or repeated points)
// that leaves the linear system without a unique solution.

#include <limits>
#include <vector>

#include <Eigen/Core>

namespace flysfm {

// The 7-point algorithm (exactly 7 matches): up to 3 rank-2 solutions.
std::vector<Eigen::Matrix3d> FundamentalFromSevenPoints(
    const std::vector<Eigen::Vector2d>& points1,
    const std::vector<Eigen::Vector2d>& points2);

// The normalized 8-point algorithm (n >= 8 matches, least squares for n > 8)
// with the rank-2 constraint enforced: at most one solution.
std::vector<Eigen::Matrix3d> FundamentalFromEightPoints(
    const std::vector<Eigen::Vector2d>& points1,
    const std::vector<Eigen::Vector2d>& points2);

// Squared Sampson distance of a match to the epipolar geometry: the
// first-order approximation of the squared distance, in the 4D space of
// (x1, x2), to the nearest exactly matching pair. Units of the points.
inline double FundamentalSampsonError(const Eigen::Matrix3d& F,
                                      const Eigen::Vector2d& x1,
                                      const Eigen::Vector2d& x2) {
  const double f0 = F(0, 0) * x1.x() + F(0, 1) * x1.y() + F(0, 2);
  const double f1 = F(1, 0) * x1.x() + F(1, 1) * x1.y() + F(1, 2);
  const double f2 = F(2, 0) * x1.x() + F(2, 1) * x1.y() + F(2, 2);
  const double g0 = F(0, 0) * x2.x() + F(1, 0) * x2.y() + F(2, 0);
  const double g1 = F(0, 1) * x2.x() + F(1, 1) * x2.y() + F(2, 1);
  const double c = x2.x() * f0 + x2.y() * f1 + f2;
  const double denominator = f0 * f0 + f1 * f1 + g0 * g0 + g1 * g1;
  if (!(denominator > 0)) return std::numeric_limits<double>::infinity();
  return c * c / denominator;
}

// F = K2^-T E K1^-1 and back.
Eigen::Matrix3d FundamentalFromEssential(const Eigen::Matrix3d& E,
                                         const Eigen::Matrix3d& K1,
                                         const Eigen::Matrix3d& K2);
Eigen::Matrix3d EssentialFromFundamental(const Eigen::Matrix3d& F,
                                         const Eigen::Matrix3d& K1,
                                         const Eigen::Matrix3d& K2);

// The closest rank-2 matrix (smallest singular value set to zero).
Eigen::Matrix3d EnforceRankTwo(const Eigen::Matrix3d& matrix);

// Relative difference of two matrices defined up to scale and sign:
// min over the sign of ||A/|A| -+ B/|B||| (Frobenius). 0 for equal matrices.
double ProjectiveMatrixDistance(const Eigen::Matrix3d& A,
                                const Eigen::Matrix3d& B);

}  // namespace flysfm
