#include "geometry/homography_matrix.h"

#include <cmath>

#include <Eigen/Dense>

#include "geometry/normalization.h"

namespace flysfm {
namespace {

constexpr double kRankTolerance = 1e-10;

}  // namespace

std::vector<Eigen::Matrix3d> HomographyFromPoints(
    const std::vector<Eigen::Vector2d>& points1,
    const std::vector<Eigen::Vector2d>& points2) {
  std::vector<Eigen::Matrix3d> models;
  if (points1.size() != points2.size() || points1.size() < 4 ||
      !AllFinite(points1) || !AllFinite(points2)) {
    return models;
  }
  std::vector<Eigen::Vector2d> n1, n2;
  Eigen::Matrix3d T1, T2;
  if (!NormalizePoints(points1, &n1, &T1) || !NormalizePoints(points2, &n2, &T2)) {
    return models;
  }
  const int n = static_cast<int>(n1.size());
  Eigen::Matrix<double, Eigen::Dynamic, 9> A(2 * n, 9);
  for (int i = 0; i < n; ++i) {
    const double x = n1[i].x(), y = n1[i].y();
    const double u = n2[i].x(), v = n2[i].y();
    A.row(2 * i) << 0, 0, 0, -x, -y, -1, v * x, v * y, v;
    A.row(2 * i + 1) << x, y, 1, 0, 0, 0, -u * x, -u * y, -u;
  }
  Eigen::Matrix<double, 9, 9> R;
  if (2 * n > 9) {
    Eigen::HouseholderQR<Eigen::Matrix<double, Eigen::Dynamic, 9>> qr(A);
    R = qr.matrixQR().topRows<9>().triangularView<Eigen::Upper>();
  } else {
    R.setZero();
    R.topRows(2 * n) = A;
  }
  Eigen::JacobiSVD<Eigen::Matrix<double, 9, 9>> svd(R, Eigen::ComputeFullV);
  const auto& sigma = svd.singularValues();
  if (!(sigma(7) > kRankTolerance * sigma(0))) return models;
  const Eigen::Matrix<double, 9, 1> h = svd.matrixV().col(8);
  Eigen::Matrix3d Hn;
  Hn << h(0), h(1), h(2), h(3), h(4), h(5), h(6), h(7), h(8);
  // A (near-)singular homography maps the plane onto a line or a point: the
  // sample was degenerate.
  const Eigen::Vector3d hn_sigma = Hn.jacobiSvd().singularValues();
  if (!(hn_sigma(2) > 1e-8 * hn_sigma(0))) return models;
  Eigen::Matrix3d H = T2.inverse() * Hn * T1;
  const double norm = H.norm();
  if (!(norm > 0) || !H.allFinite()) return models;
  models.push_back(H / norm);
  return models;
}

double HomographyTransferError(const Eigen::Matrix3d& H,
                               const Eigen::Vector2d& x1,
                               const Eigen::Vector2d& x2) {
  const Eigen::Vector3d p = H * x1.homogeneous();
  if (p.z() == 0) return std::numeric_limits<double>::infinity();
  return (p.hnormalized() - x2).squaredNorm();
}

}  // namespace flysfm
