#include "geometry/fundamental_matrix.h"

#include <cmath>

#include <Eigen/Dense>

#include "geometry/normalization.h"
#include "geometry/polynomial.h"

namespace flysfm {
namespace {

// Relative size under which a singular value or pivot counts as zero.
constexpr double kRankTolerance = 1e-10;

// One row of the epipolar constraint for F stored row-major.
Eigen::Matrix<double, 1, 9> EpipolarRow(const Eigen::Vector2d& x1,
                                        const Eigen::Vector2d& x2) {
  Eigen::Matrix<double, 1, 9> row;
  row << x2.x() * x1.x(), x2.x() * x1.y(), x2.x(), x2.y() * x1.x(),
      x2.y() * x1.y(), x2.y(), x1.x(), x1.y(), 1.0;
  return row;
}

Eigen::Matrix3d FromRowMajor(const Eigen::Matrix<double, 9, 1>& f) {
  Eigen::Matrix3d F;
  F << f(0), f(1), f(2), f(3), f(4), f(5), f(6), f(7), f(8);
  return F;
}

double Det3(const Eigen::Vector3d& a, const Eigen::Vector3d& b,
            const Eigen::Vector3d& c) {
  return a.dot(b.cross(c));
}

bool ValidInput(const std::vector<Eigen::Vector2d>& points1,
                const std::vector<Eigen::Vector2d>& points2, std::size_t min) {
  return points1.size() == points2.size() && points1.size() >= min &&
         AllFinite(points1) && AllFinite(points2);
}

}  // namespace

std::vector<Eigen::Matrix3d> FundamentalFromSevenPoints(
    const std::vector<Eigen::Vector2d>& points1,
    const std::vector<Eigen::Vector2d>& points2) {
  std::vector<Eigen::Matrix3d> models;
  if (!ValidInput(points1, points2, 7) || points1.size() != 7) return models;
  std::vector<Eigen::Vector2d> n1, n2;
  Eigen::Matrix3d T1, T2;
  if (!NormalizePoints(points1, &n1, &T1) || !NormalizePoints(points2, &n2, &T2)) {
    return models;
  }
  Eigen::Matrix<double, 9, 7> At;
  for (int i = 0; i < 7; ++i) At.col(i) = EpipolarRow(n1[i], n2[i]).transpose();
  Eigen::ColPivHouseholderQR<Eigen::Matrix<double, 9, 7>> qr(At);
  qr.setThreshold(kRankTolerance);
  if (qr.rank() < 7) return models;
  const Eigen::Matrix<double, 9, 9> Q = qr.householderQ();
  const Eigen::Matrix3d F1 = FromRowMajor(Q.col(7));
  const Eigen::Matrix3d F2 = FromRowMajor(Q.col(8));
  // det(A + alpha B) = c3 alpha^3 + c2 alpha^2 + c1 alpha + c0, expanded
  // column by column (the determinant is multilinear in the columns).
  const Eigen::Matrix3d& A = F2;
  const Eigen::Matrix3d B = F1 - F2;
  const Eigen::Vector3d a0 = A.col(0), a1 = A.col(1), a2 = A.col(2);
  const Eigen::Vector3d b0 = B.col(0), b1 = B.col(1), b2 = B.col(2);
  const double c0 = Det3(a0, a1, a2);
  const double c1 = Det3(b0, a1, a2) + Det3(a0, b1, a2) + Det3(a0, a1, b2);
  const double c2 = Det3(a0, b1, b2) + Det3(b0, a1, b2) + Det3(b0, b1, a2);
  const double c3 = Det3(b0, b1, b2);
  for (const double alpha : RealCubicRoots(c3, c2, c1, c0)) {
    if (!std::isfinite(alpha)) continue;
    Eigen::Matrix3d F = T2.transpose() * (A + alpha * B) * T1;
    const double norm = F.norm();
    if (!(norm > 0) || !F.allFinite()) continue;
    models.push_back(F / norm);
  }
  return models;
}

std::vector<Eigen::Matrix3d> FundamentalFromEightPoints(
    const std::vector<Eigen::Vector2d>& points1,
    const std::vector<Eigen::Vector2d>& points2) {
  std::vector<Eigen::Matrix3d> models;
  if (!ValidInput(points1, points2, 8)) return models;
  std::vector<Eigen::Vector2d> n1, n2;
  Eigen::Matrix3d T1, T2;
  if (!NormalizePoints(points1, &n1, &T1) || !NormalizePoints(points2, &n2, &T2)) {
    return models;
  }
  const int n = static_cast<int>(n1.size());
  Eigen::Matrix<double, Eigen::Dynamic, 9> A(n, 9);
  for (int i = 0; i < n; ++i) A.row(i) = EpipolarRow(n1[i], n2[i]);
  // Reduce to 9x9 by QR, then the SVD of R has A's right singular vectors.
  Eigen::Matrix<double, 9, 9> R;
  if (n > 9) {
    Eigen::HouseholderQR<Eigen::Matrix<double, Eigen::Dynamic, 9>> qr(A);
    R = qr.matrixQR().topRows<9>().triangularView<Eigen::Upper>();
  } else {
    R.setZero();
    R.topRows(n) = A;
  }
  Eigen::JacobiSVD<Eigen::Matrix<double, 9, 9>> svd(R, Eigen::ComputeFullV);
  const auto& sigma = svd.singularValues();
  if (!(sigma(7) > kRankTolerance * sigma(0))) return models;
  const Eigen::Matrix3d F =
      T2.transpose() * EnforceRankTwo(FromRowMajor(svd.matrixV().col(8))) * T1;
  const double norm = F.norm();
  if (!(norm > 0) || !F.allFinite()) return models;
  models.push_back(F / norm);
  return models;
}

Eigen::Matrix3d EnforceRankTwo(const Eigen::Matrix3d& matrix) {
  Eigen::JacobiSVD<Eigen::Matrix3d> svd(matrix, Eigen::ComputeFullU |
                                                    Eigen::ComputeFullV);
  Eigen::Vector3d sigma = svd.singularValues();
  sigma(2) = 0;
  return svd.matrixU() * sigma.asDiagonal() * svd.matrixV().transpose();
}

Eigen::Matrix3d FundamentalFromEssential(const Eigen::Matrix3d& E,
                                         const Eigen::Matrix3d& K1,
                                         const Eigen::Matrix3d& K2) {
  return K2.transpose().inverse() * E * K1.inverse();
}

Eigen::Matrix3d EssentialFromFundamental(const Eigen::Matrix3d& F,
                                         const Eigen::Matrix3d& K1,
                                         const Eigen::Matrix3d& K2) {
  return K2.transpose() * F * K1;
}

double ProjectiveMatrixDistance(const Eigen::Matrix3d& A,
                                const Eigen::Matrix3d& B) {
  const double na = A.norm();
  const double nb = B.norm();
  if (!(na > 0) || !(nb > 0)) return std::numeric_limits<double>::infinity();
  const Eigen::Matrix3d a = A / na;
  const Eigen::Matrix3d b = B / nb;
  return std::min((a - b).norm(), (a + b).norm());
}

}  // namespace flysfm
