#include "geometry/similarity.h"

#include <cmath>

#include <Eigen/Dense>

#include "geometry/normalization.h"

namespace flysfm {
namespace {

// Relative size of the second singular value of a centred point set below
// which the points count as collinear.
constexpr double kCollinearTolerance = 1e-9;

struct Alignment {
  double scale = 1;
  Eigen::Matrix3d rotation;
  Eigen::Vector3d translation;
};

bool SpreadInTwoDirections(const Eigen::Matrix3Xd& centred) {
  const Eigen::Vector3d sigma = centred.jacobiSvd().singularValues();
  return sigma(0) > 0 && sigma(1) > kCollinearTolerance * sigma(0);
}

std::optional<Alignment> Align(const std::vector<Eigen::Vector3d>& src,
                               const std::vector<Eigen::Vector3d>& dst,
                               bool with_scale) {
  if (src.size() != dst.size() || src.size() < 3 || !AllFinite(src) ||
      !AllFinite(dst)) {
    return std::nullopt;
  }
  const int n = static_cast<int>(src.size());
  Eigen::Matrix3Xd S(3, n), D(3, n);
  for (int i = 0; i < n; ++i) {
    S.col(i) = src[i];
    D.col(i) = dst[i];
  }
  const Eigen::Vector3d src_mean = S.rowwise().mean();
  const Eigen::Vector3d dst_mean = D.rowwise().mean();
  S.colwise() -= src_mean;
  D.colwise() -= dst_mean;
  if (!SpreadInTwoDirections(S) || !SpreadInTwoDirections(D)) return std::nullopt;
  const Eigen::Matrix3d covariance = D * S.transpose() / n;
  Eigen::JacobiSVD<Eigen::Matrix3d> svd(covariance, Eigen::ComputeFullU |
                                                        Eigen::ComputeFullV);
  Eigen::Vector3d signs = Eigen::Vector3d::Ones();
  if (svd.matrixU().determinant() * svd.matrixV().determinant() < 0) {
    signs(2) = -1;
  }
  Alignment alignment;
  alignment.rotation =
      svd.matrixU() * signs.asDiagonal() * svd.matrixV().transpose();
  if (with_scale) {
    const double src_variance = S.squaredNorm() / n;
    alignment.scale = svd.singularValues().dot(signs) / src_variance;
    if (!(alignment.scale > 0) || !std::isfinite(alignment.scale)) {
      return std::nullopt;
    }
  }
  alignment.translation =
      dst_mean - alignment.scale * alignment.rotation * src_mean;
  if (!alignment.rotation.allFinite() || !alignment.translation.allFinite()) {
    return std::nullopt;
  }
  return alignment;
}

}  // namespace

std::optional<Sim3d> SimilarityFromPoints(const std::vector<Eigen::Vector3d>& src,
                                          const std::vector<Eigen::Vector3d>& dst) {
  const auto alignment = Align(src, dst, true);
  if (!alignment) return std::nullopt;
  return Sim3d(alignment->scale, Eigen::Quaterniond(alignment->rotation),
               alignment->translation);
}

std::optional<Rigid3d> RigidFromPoints(const std::vector<Eigen::Vector3d>& src,
                                       const std::vector<Eigen::Vector3d>& dst) {
  const auto alignment = Align(src, dst, false);
  if (!alignment) return std::nullopt;
  return Rigid3d(alignment->rotation, alignment->translation);
}

}  // namespace flysfm
