#include "geometry/two_view_geometry.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include <Eigen/Dense>

#include "geometry/essential_matrix.h"
#include "geometry/estimators.h"
#include "geometry/fundamental_matrix.h"
#include "geometry/gric.h"
#include "geometry/homography_matrix.h"
#include "geometry/triangulation.h"

namespace flysfm {
namespace {

// Matches whose coordinates are all finite, as indices into the input.
std::vector<int> FiniteMatches(const std::vector<Eigen::Vector2d>& points1,
                               const std::vector<Eigen::Vector2d>& points2) {
  std::vector<int> valid;
  for (std::size_t i = 0; i < points1.size(); ++i) {
    if (points1[i].allFinite() && points2[i].allFinite()) {
      valid.push_back(static_cast<int>(i));
    }
  }
  return valid;
}

template <typename T>
std::vector<T> Select(const std::vector<T>& values, const std::vector<int>& indices) {
  std::vector<T> selected(indices.size());
  for (std::size_t k = 0; k < indices.size(); ++k) selected[k] = values[indices[k]];
  return selected;
}

std::vector<char> Mask(const std::vector<double>& squared_errors, double threshold2,
                       int* count) {
  std::vector<char> mask(squared_errors.size(), 0);
  *count = 0;
  for (std::size_t i = 0; i < mask.size(); ++i) {
    if (squared_errors[i] <= threshold2) {
      mask[i] = 1;
      ++*count;
    }
  }
  return mask;
}

// Rotation R minimizing sum |b2 - R b1|^2 over unit bearing vectors.
Eigen::Matrix3d RotationFromBearings(const std::vector<Eigen::Vector3d>& b1,
                                     const std::vector<Eigen::Vector3d>& b2) {
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Zero();
  for (std::size_t i = 0; i < b1.size(); ++i) covariance += b2[i] * b1[i].transpose();
  Eigen::JacobiSVD<Eigen::Matrix3d> svd(covariance, Eigen::ComputeFullU |
                                                        Eigen::ComputeFullV);
  Eigen::Vector3d signs = Eigen::Vector3d::Ones();
  if (svd.matrixU().determinant() * svd.matrixV().determinant() < 0) signs(2) = -1;
  return svd.matrixU() * signs.asDiagonal() * svd.matrixV().transpose();
}

struct CalibrationInput {
  Eigen::Matrix3d K1, K2;
  std::vector<Eigen::Vector2d> normalized1, normalized2;  // compact (valid)
};

// The shared core: `p1`, `p2` are the valid matches in (undistorted) pixels;
// `calibration` is set when both cameras are known.
TwoViewGeometry EstimateCore(const std::vector<Eigen::Vector2d>& p1,
                             const std::vector<Eigen::Vector2d>& p2,
                             const CalibrationInput* calibration,
                             const TwoViewGeometryOptions& options) {
  TwoViewGeometry geometry;
  const int n = static_cast<int>(p1.size());
  geometry.inlier_mask.assign(n, 0);
  const double threshold2 = options.max_error_px * options.max_error_px;
  RansacOptions ransac = options.ransac;
  ransac.max_error = options.max_error_px;
  // A model with fewer inliers than a verified pair needs is never used: no
  // model search draws more samples than finding one with that many takes.
  // On a photo's candidates that do not overlap it (a dozen or two chance
  // matches left by the ratio test) this stops the search after tens of
  // samples instead of thousands.
  const auto at_least = [&](const RansacOptions& base, int min_num_inliers) {
    RansacOptions bounded = base;
    bounded.min_inlier_ratio =
        std::max(base.min_inlier_ratio, std::min(1.0, min_num_inliers / static_cast<double>(n)));
    return bounded;
  };

  std::vector<double> errors_f(n, std::numeric_limits<double>::infinity());
  std::vector<double> errors_h = errors_f, errors_e = errors_f;
  std::vector<char> mask_f(n, 0), mask_h(n, 0), mask_e(n, 0);
  bool have_f = false, have_h = false, have_e = false;

  if (n >= FundamentalEstimator::kMinSampleSize) {
    const auto report =
        EstimateFundamentalMatrix(p1, p2, at_least(ransac, options.min_num_inliers_f));
    if (report.success) {
      have_f = true;
      geometry.F = report.model;
      for (int i = 0; i < n; ++i) errors_f[i] = FundamentalSampsonError(geometry.F, p1[i], p2[i]);
      mask_f = Mask(errors_f, threshold2, &geometry.num_inliers_f);
    }
  }
  if (n >= HomographyEstimator::kMinSampleSize) {
    // H can only win GRIC when it explains most of F's inliers (an H
    // residual costs up to twice an F residual): searching for an H with
    // less than half of them is wasted time on general scenes.
    RansacOptions ransac_h = at_least(ransac, options.min_num_inliers_h);
    if (have_f) {
      ransac_h.min_inlier_ratio = std::max(
          ransac_h.min_inlier_ratio, 0.5 * geometry.num_inliers_f / static_cast<double>(n));
    }
    const auto report = EstimateHomographyMatrix(p1, p2, ransac_h);
    if (report.success) {
      have_h = true;
      geometry.H = report.model;
      for (int i = 0; i < n; ++i) errors_h[i] = HomographySampsonError(geometry.H, p1[i], p2[i]);
      mask_h = Mask(errors_h, threshold2, &geometry.num_inliers_h);
    }
  }
  if (calibration != nullptr && n >= EssentialEstimator::kMinSampleSize) {
    RansacOptions ransac_e = at_least(ransac, options.min_num_inliers_f);
    const double focal = 0.25 * (calibration->K1(0, 0) + calibration->K1(1, 1) +
                                 calibration->K2(0, 0) + calibration->K2(1, 1));
    ransac_e.max_error = options.max_error_px / focal;
    const auto report = EstimateEssentialMatrix(calibration->normalized1,
                                                calibration->normalized2, ransac_e);
    if (report.success) {
      have_e = true;
      geometry.E = report.model;
      const Eigen::Matrix3d F_e =
          FundamentalFromEssential(geometry.E, calibration->K1, calibration->K2);
      for (int i = 0; i < n; ++i) errors_e[i] = FundamentalSampsonError(F_e, p1[i], p2[i]);
      mask_e = Mask(errors_e, threshold2, &geometry.num_inliers_e);
    }
  }

  // GRIC over the matches that some model explains: gross outliers say
  // nothing about which model is right.
  std::vector<int> informative;
  for (int i = 0; i < n; ++i) {
    if (mask_f[i] || mask_h[i] || mask_e[i]) informative.push_back(i);
  }
  const bool general_from_f = have_f && geometry.num_inliers_f >= geometry.num_inliers_e;
  {
    std::vector<double> inlier_errors;
    const std::vector<double>& errors = general_from_f ? errors_f : errors_e;
    const std::vector<char>& mask = general_from_f ? mask_f : mask_e;
    for (int i = 0; i < n; ++i) {
      if (mask[i]) inlier_errors.push_back(errors[i]);
    }
    geometry.sigma_px = std::max(options.min_gric_sigma_px,
                                 EstimateNoiseSigma(inlier_errors, 1));
  }
  auto gric_of = [&](const std::vector<double>& errors, GricModel model) {
    return Gric(Select(errors, informative), geometry.sigma_px, model);
  };
  if (have_f && geometry.num_inliers_f >= options.min_num_inliers_f) {
    geometry.gric_f = gric_of(errors_f, kGricFundamental);
  }
  if (have_e && geometry.num_inliers_e >= options.min_num_inliers_f) {
    geometry.gric_e = gric_of(errors_e, kGricEssential);
  }
  if (have_h && geometry.num_inliers_h >= options.min_num_inliers_h) {
    geometry.gric_h = gric_of(errors_h, kGricHomography);
  }
  const double best = std::min({geometry.gric_f, geometry.gric_e, geometry.gric_h});
  if (!std::isfinite(best)) return geometry;  // kDegenerate

  if (best == geometry.gric_e) {
    geometry.config = TwoViewConfiguration::kCalibrated;
    geometry.inlier_mask = mask_e;
    geometry.num_inliers = geometry.num_inliers_e;
  } else if (best == geometry.gric_h) {
    geometry.inlier_mask = mask_h;
    geometry.num_inliers = geometry.num_inliers_h;
    geometry.config = TwoViewConfiguration::kPlanarOrPanoramic;
    if (calibration != nullptr) {
      // Pure rotation when a rotation-only homography K2 R K1^-1 explains
      // (nearly) all of H's inliers.
      std::vector<Eigen::Vector3d> b1, b2;
      for (int i = 0; i < n; ++i) {
        if (!mask_h[i]) continue;
        b1.push_back(calibration->normalized1[i].homogeneous().normalized());
        b2.push_back(calibration->normalized2[i].homogeneous().normalized());
      }
      const Eigen::Matrix3d R = RotationFromBearings(b1, b2);
      const Eigen::Matrix3d H_rotation =
          calibration->K2 * R * calibration->K1.inverse();
      int kept = 0;
      for (int i = 0; i < n; ++i) {
        kept += mask_h[i] &&
                HomographySampsonError(H_rotation, p1[i], p2[i]) <= threshold2;
      }
      if (kept >= options.panoramic_min_inlier_ratio * geometry.num_inliers_h) {
        geometry.config = TwoViewConfiguration::kPanoramic;
        if (options.compute_relative_pose) {
          geometry.has_pose = true;
          geometry.cam2_from_cam1 = Rigid3d(R, Eigen::Vector3d::Zero());
          geometry.median_tri_angle_deg = 0;
        }
      } else {
        geometry.config = TwoViewConfiguration::kPlanar;
      }
    }
  } else {
    geometry.config = TwoViewConfiguration::kUncalibrated;
    geometry.inlier_mask = mask_f;
    geometry.num_inliers = geometry.num_inliers_f;
  }

  // When F wins, the cameras given may be a guess: E's pose, from F's
  // inliers, is then the start a self-calibration needs (the caller knows
  // whether the cameras are).
  const bool pose_from_e =
      calibration != nullptr && options.compute_relative_pose && have_e &&
      (geometry.config == TwoViewConfiguration::kCalibrated ||
       geometry.config == TwoViewConfiguration::kPlanar ||
       (geometry.config == TwoViewConfiguration::kUncalibrated &&
        geometry.num_inliers_e >= options.min_num_inliers_f));
  if (pose_from_e) {
    std::vector<Eigen::Vector2d> x1, x2;
    for (int i = 0; i < n; ++i) {
      if (!geometry.inlier_mask[i]) continue;
      x1.push_back(calibration->normalized1[i]);
      x2.push_back(calibration->normalized2[i]);
    }
    Rigid3d pose;
    std::vector<Eigen::Vector3d> points;
    std::vector<char> in_front;
    if (RelativePoseFromEssential(geometry.E, x1, x2, &pose, &points, &in_front) > 0) {
      geometry.has_pose = true;
      geometry.cam2_from_cam1 = pose;
      const Eigen::Vector3d center2 = ProjectionCenter(pose);
      std::vector<double> angles;
      for (std::size_t k = 0; k < points.size(); ++k) {
        if (in_front[k]) {
          angles.push_back(TriangulationAngleDeg(Eigen::Vector3d::Zero(), center2, points[k]));
        }
      }
      if (!angles.empty()) {
        std::nth_element(angles.begin(), angles.begin() + angles.size() / 2, angles.end());
        geometry.median_tri_angle_deg = angles[angles.size() / 2];
      }
    }
  }
  return geometry;
}

// Maps a result on the valid (compact) matches back to all matches.
TwoViewGeometry Expand(TwoViewGeometry compact, const std::vector<int>& valid,
                       std::size_t num_matches) {
  std::vector<char> mask(num_matches, 0);
  for (std::size_t k = 0; k < valid.size() && k < compact.inlier_mask.size(); ++k) {
    mask[valid[k]] = compact.inlier_mask[k];
  }
  compact.inlier_mask = std::move(mask);
  return compact;
}

}  // namespace

RansacResult<Eigen::Matrix3d> EstimateFundamentalMatrix(
    const std::vector<Eigen::Vector2d>& points1,
    const std::vector<Eigen::Vector2d>& points2, const RansacOptions& options) {
  if (points1.size() != points2.size()) return {};
  return Ransac(FundamentalEstimator(points1, points2), options);
}

RansacResult<Eigen::Matrix3d> EstimateHomographyMatrix(
    const std::vector<Eigen::Vector2d>& points1,
    const std::vector<Eigen::Vector2d>& points2, const RansacOptions& options) {
  if (points1.size() != points2.size()) return {};
  return Ransac(HomographyEstimator(points1, points2), options);
}

RansacResult<Eigen::Matrix3d> EstimateEssentialMatrix(
    const std::vector<Eigen::Vector2d>& normalized1,
    const std::vector<Eigen::Vector2d>& normalized2, const RansacOptions& options) {
  if (normalized1.size() != normalized2.size()) return {};
  return Ransac(EssentialEstimator(normalized1, normalized2), options);
}

std::string TwoViewConfigurationName(TwoViewConfiguration config) {
  switch (config) {
    case TwoViewConfiguration::kDegenerate: return "DEGENERATE";
    case TwoViewConfiguration::kCalibrated: return "CALIBRATED";
    case TwoViewConfiguration::kUncalibrated: return "UNCALIBRATED";
    case TwoViewConfiguration::kPlanar: return "PLANAR";
    case TwoViewConfiguration::kPanoramic: return "PANORAMIC";
    case TwoViewConfiguration::kPlanarOrPanoramic: return "PLANAR_OR_PANORAMIC";
  }
  return "UNKNOWN";
}

std::string TwoViewGeometryOptionsProblem(const TwoViewGeometryOptions& o) {
  const std::string name = "TwoViewGeometryOptions: ";
  if (o.min_num_inliers_f < 7) return name + "min_num_inliers_f must be >= 7";
  if (o.min_num_inliers_h < 4) return name + "min_num_inliers_h must be >= 4";
  if (!(o.max_error_px > 0) || !std::isfinite(o.max_error_px)) {
    return name + "max_error_px must be a finite number > 0";
  }
  if (!(o.min_gric_sigma_px > 0) || !std::isfinite(o.min_gric_sigma_px)) {
    return name + "min_gric_sigma_px must be a finite number > 0";
  }
  if (!(o.panoramic_min_inlier_ratio > 0 && o.panoramic_min_inlier_ratio <= 1)) {
    return name + "panoramic_min_inlier_ratio must be in (0, 1]";
  }
  RansacOptions ransac = o.ransac;
  ransac.max_error = o.max_error_px;
  return RansacOptionsProblem(ransac);
}

bool TwoViewGeometryOptions::Check() const {
  return TwoViewGeometryOptionsProblem(*this).empty();
}

Eigen::Matrix3d CalibrationMatrix(const Camera& camera) {
  const int num_focal = camera.NumFocalParams();
  Eigen::Matrix3d K = Eigen::Matrix3d::Identity();
  K(0, 0) = camera.params[0];
  K(1, 1) = camera.params[num_focal - 1];
  K(0, 2) = camera.params[num_focal];
  K(1, 2) = camera.params[num_focal + 1];
  return K;
}

TwoViewGeometry EstimateUncalibratedTwoViewGeometry(
    const std::vector<Eigen::Vector2d>& points1,
    const std::vector<Eigen::Vector2d>& points2,
    const TwoViewGeometryOptions& options) {
  ThrowIfInvalid(TwoViewGeometryOptionsProblem(options));
  if (points1.size() != points2.size()) return {};
  const std::vector<int> valid = FiniteMatches(points1, points2);
  TwoViewGeometry compact =
      EstimateCore(Select(points1, valid), Select(points2, valid), nullptr, options);
  return Expand(std::move(compact), valid, points1.size());
}

TwoViewGeometry EstimateCalibratedTwoViewGeometry(
    const Camera& camera1, const std::vector<Eigen::Vector2d>& points1,
    const Camera& camera2, const std::vector<Eigen::Vector2d>& points2,
    const TwoViewGeometryOptions& options) {
  ThrowIfInvalid(TwoViewGeometryOptionsProblem(options));
  if (points1.size() != points2.size() || !camera1.IsValid() || !camera2.IsValid()) {
    return {};
  }
  CalibrationInput calibration;
  calibration.K1 = CalibrationMatrix(camera1);
  calibration.K2 = CalibrationMatrix(camera2);
  std::vector<int> valid;
  std::vector<Eigen::Vector2d> p1, p2;
  for (std::size_t i = 0; i < points1.size(); ++i) {
    if (!points1[i].allFinite() || !points2[i].allFinite()) continue;
    const Eigen::Vector2d n1 = camera1.CamFromImg(points1[i]);
    const Eigen::Vector2d n2 = camera2.CamFromImg(points2[i]);
    if (!n1.allFinite() || !n2.allFinite()) continue;
    valid.push_back(static_cast<int>(i));
    calibration.normalized1.push_back(n1);
    calibration.normalized2.push_back(n2);
    p1.push_back((calibration.K1 * n1.homogeneous()).head<2>());
    p2.push_back((calibration.K2 * n2.homogeneous()).head<2>());
  }
  TwoViewGeometry compact = EstimateCore(p1, p2, &calibration, options);
  return Expand(std::move(compact), valid, points1.size());
}

}  // namespace flysfm
