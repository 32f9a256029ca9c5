#include "geometry/focal_from_fundamental.h"

#include <cmath>

#include <Eigen/SVD>

#include "geometry/fundamental_matrix.h"

namespace flysfm {
namespace {

// The mean gap of `fundamentals`, already moved to the principal point.
double MeanGap(const std::vector<Eigen::Matrix3d>& centred, double focal_length) {
  double sum = 0;
  for (const Eigen::Matrix3d& F : centred) {
    sum += EssentialSingularValueGap(F, Eigen::Vector2d::Zero(), focal_length);
  }
  return sum / double(centred.size());
}

}  // namespace

bool FocalFromFundamentalOptions::Check() const {
  return min_focal_length_factor > 0 && max_focal_length_factor > min_focal_length_factor &&
         num_samples >= 3 &&
         min_contrast >= 1 && min_gap_rise >= 0;
}

double EssentialSingularValueGap(const Eigen::Matrix3d& F,
                                 const Eigen::Vector2d& principal_point,
                                 double focal_length) {
  // pixel = T * (centred pixel); centred pixel = K * normalized.
  Eigen::Matrix3d T_K = Eigen::Matrix3d::Identity();
  T_K(0, 0) = T_K(1, 1) = focal_length;
  T_K(0, 2) = principal_point.x();
  T_K(1, 2) = principal_point.y();
  const Eigen::Matrix3d E = EssentialFromFundamental(F, T_K, T_K);
  const Eigen::Vector3d s = E.jacobiSvd().singularValues();
  if (!s.allFinite() || s(0) <= 0) return 1;
  return (s(0) - s(1)) / (s(0) + s(1));
}

int FocalFromFundamentals(const std::vector<Eigen::Matrix3d>& fundamentals,
                          const Eigen::Vector2d& principal_point, double longer_side,
                          double reference_focal_length,
                          const FocalFromFundamentalOptions& options, double* focal_length) {
  if (fundamentals.empty() || !options.Check() || !principal_point.allFinite() ||
      !(longer_side > 0) || !std::isfinite(longer_side) || !(reference_focal_length > 0)) {
    return 0;
  }
  // Each F moved to the principal point and scaled to unit norm, so that no
  // pair weighs more for its scale.
  Eigen::Matrix3d T = Eigen::Matrix3d::Identity();
  T.topRightCorner<2, 1>() = principal_point;
  std::vector<Eigen::Matrix3d> centred;
  for (const Eigen::Matrix3d& F : fundamentals) {
    const Eigen::Matrix3d moved = T.transpose() * F * T;
    if (!moved.allFinite() || moved.norm() <= 0) return 0;
    centred.push_back(moved / moved.norm());
  }
  const double log_min = std::log(options.min_focal_length_factor * longer_side);
  const double step =
      std::log(options.max_focal_length_factor / options.min_focal_length_factor) /
      double(options.num_samples - 1);
  const auto focal_at = [&](double k) { return std::exp(log_min + k * step); };
  int best = 0;
  double best_gap = MeanGap(centred, focal_at(0));
  for (int k = 1; k < options.num_samples; ++k) {
    const double gap = MeanGap(centred, focal_at(k));
    if (gap < best_gap) {
      best = k;
      best_gap = gap;
    }
  }
  if (best == 0 || best == options.num_samples - 1) return 0;
  // Golden-section search between the neighbouring samples, in log f.
  constexpr double kInvPhi = 0.6180339887498949;
  double a = best - 1.0, b = best + 1.0;
  double c = b - kInvPhi * (b - a), d = a + kInvPhi * (b - a);
  double gap_c = MeanGap(centred, focal_at(c)), gap_d = MeanGap(centred, focal_at(d));
  for (int iteration = 0; iteration < 40; ++iteration) {
    if (gap_c < gap_d) {
      b = d;
      d = c;
      gap_d = gap_c;
      c = b - kInvPhi * (b - a);
      gap_c = MeanGap(centred, focal_at(c));
    } else {
      a = c;
      c = d;
      gap_c = gap_d;
      d = a + kInvPhi * (b - a);
      gap_d = MeanGap(centred, focal_at(d));
    }
  }
  const double focal = focal_at(0.5 * (a + b));
  const double gap = MeanGap(centred, focal);
  const double reference_gap = MeanGap(centred, reference_focal_length);
  if (reference_gap < options.min_contrast * gap || reference_gap < gap + options.min_gap_rise) {
    return 0;
  }
  *focal_length = focal;
  return 1;
}

}  // namespace flysfm
