#include "geometry/similarity.h"

#include <cmath>
#include <cstddef>

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

// For Ransac(): the minimal sample and the inliers are fitted by the same
// least squares, as Umeyama on three points is exact and a separate minimal
// solver would only duplicate it.
class SimilarityEstimator {
 public:
  using Model = Sim3d;
  static constexpr int kMinSampleSize = 3;

  SimilarityEstimator(const std::vector<Eigen::Vector3d>& src,
                      const std::vector<Eigen::Vector3d>& dst)
      : src_(src), dst_(dst) {}

  int NumData() const { return static_cast<int>(src_.size()); }

  void MinimalSolve(const std::vector<int>& sample,
                    std::vector<Model>* models) const {
    Fit(sample, models);
  }

  void NonMinimalSolve(const std::vector<int>& indices, const Model&,
                       std::vector<Model>* models) const {
    Fit(indices, models);
  }

  // On a fixed inlier set the least-squares fit already minimizes the error
  // below, so there is nothing non-linear to refine: this is that fit again,
  // which matters only when local optimisation is off.
  bool Refine(const std::vector<int>& inliers, Model* model) const {
    std::vector<Model> fits;
    Fit(inliers, &fits);
    if (fits.empty()) return false;
    *model = fits.front();
    return true;
  }

  double SquaredError(const Model& dst_from_src, int i) const {
    return (dst_[i] - dst_from_src * src_[i]).squaredNorm();
  }

 private:
  void Fit(const std::vector<int>& indices, std::vector<Model>* models) const {
    std::vector<Eigen::Vector3d> src(indices.size()), dst(indices.size());
    for (std::size_t k = 0; k < indices.size(); ++k) {
      src[k] = src_[indices[k]];
      dst[k] = dst_[indices[k]];
    }
    models->clear();
    if (const auto fit = SimilarityFromPoints(src, dst)) models->push_back(*fit);
  }

  const std::vector<Eigen::Vector3d>& src_;
  const std::vector<Eigen::Vector3d>& dst_;
};

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

RansacResult<Sim3d> EstimateSimilarity(const std::vector<Eigen::Vector3d>& src,
                                       const std::vector<Eigen::Vector3d>& dst,
                                       const RansacOptions& options) {
  // Options first, so that a bad configuration throws whatever the data.
  ThrowIfInvalid(RansacOptionsProblem(options));
  if (src.size() != dst.size()) return {};
  return Ransac(SimilarityEstimator(src, dst), options);
}

}  // namespace flysfm
