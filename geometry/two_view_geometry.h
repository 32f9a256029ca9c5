#pragma once

// Two-view geometry of an image pair from its matched keypoints: RANSAC for
// F (and E when both cameras are calibrated) and H, GRIC model selection, and
// the configuration of the pair.

#include <limits>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "geometry/camera.h"
#include "geometry/ransac.h"
#include "geometry/rigid3d.h"

namespace flysfm {

// RANSAC wrappers. F and H take pixels (options.max_error: Sampson distance
// in pixels); E takes normalized image coordinates (options.max_error in
// normalized units, e.g. Camera::CamFromImgThreshold(pixels)).
RansacResult<Eigen::Matrix3d> EstimateFundamentalMatrix(
    const std::vector<Eigen::Vector2d>& points1,
    const std::vector<Eigen::Vector2d>& points2, const RansacOptions& options);
RansacResult<Eigen::Matrix3d> EstimateHomographyMatrix(
    const std::vector<Eigen::Vector2d>& points1,
    const std::vector<Eigen::Vector2d>& points2, const RansacOptions& options);
RansacResult<Eigen::Matrix3d> EstimateEssentialMatrix(
    const std::vector<Eigen::Vector2d>& normalized1,
    const std::vector<Eigen::Vector2d>& normalized2, const RansacOptions& options);

enum class TwoViewConfiguration {
  kDegenerate = 0,      // no model with enough inliers, or bad input
  kCalibrated = 1,      // E selected (both cameras known)
  kUncalibrated = 2,    // F selected
  kPlanar = 3,          // H selected, cameras known, the pair has a baseline
  kPanoramic = 4,       // H selected, cameras known, pure rotation
  kPlanarOrPanoramic = 5,  // H selected, cameras unknown
};

std::string TwoViewConfigurationName(TwoViewConfiguration config);

struct TwoViewGeometryOptions {
  // N_f: F (or E) needs this many inliers to verify the pair.
  int min_num_inliers_f = 15;
  // N_h: H needs this many inliers to be a candidate.
  int min_num_inliers_h = 15;
  // Inlier threshold for all three models: Sampson distance in pixels (for E
  // measured through F = K2^-T E K1^-1, so in pixels as well).
  double max_error_px = 2.0;
  // GRIC's noise sigma is estimated from the inliers of the general model (F,
  // or E if F is absent); it is never taken below this floor (pixels), so
  // that noise-free data cannot make any residual look significant.
  double min_gric_sigma_px = 0.25;
  // With known cameras, H is a pure rotation (kPanoramic) when the best
  // rotation-only homography keeps at least this fraction of H's inliers.
  double panoramic_min_inlier_ratio = 0.9;
  // With known cameras, recover cam2_from_cam1 for kCalibrated, kPlanar (from
  // E, by cheirality) and kPanoramic (rotation only); for kUncalibrated too,
  // from E, when E had enough inliers: with guessed intrinsics GRIC prefers F
  // as soon as the guess is off, though E keeps nearly all of F's inliers.
  bool compute_relative_pose = true;
  // Sampling options shared by the three RANSAC runs; max_error is ignored.
  RansacOptions ransac;

  // True when every option is in its documented range; the functions taking
  // these options throw std::invalid_argument naming the bad one otherwise.
  bool Check() const;
};

struct TwoViewGeometry {
  TwoViewConfiguration config = TwoViewConfiguration::kDegenerate;
  // The estimated models (zero when not estimated): F and H in pixels of the
  // input (undistorted pixels K * normalized when the cameras are known),
  // E in normalized coordinates.
  Eigen::Matrix3d F = Eigen::Matrix3d::Zero();
  Eigen::Matrix3d E = Eigen::Matrix3d::Zero();
  Eigen::Matrix3d H = Eigen::Matrix3d::Zero();
  int num_inliers_f = 0;
  int num_inliers_e = 0;
  int num_inliers_h = 0;
  // GRIC of each candidate (+inf when not a candidate) and the noise sigma
  // (pixels) it used.
  double gric_f = std::numeric_limits<double>::infinity();
  double gric_e = std::numeric_limits<double>::infinity();
  double gric_h = std::numeric_limits<double>::infinity();
  double sigma_px = 0;
  // Inliers of the selected model, one flag per match.
  std::vector<char> inlier_mask;
  int num_inliers = 0;
  // Known cameras only (see TwoViewGeometryOptions::compute_relative_pose):
  // |t| = 1 for kCalibrated, kPlanar and kUncalibrated, t = 0 for
  // kPanoramic.
  bool has_pose = false;
  Rigid3d cam2_from_cam1;
  // Median triangulation angle (degrees) of the inliers in front of both
  // cameras, with the pose.
  double median_tri_angle_deg = 0;
};

// Cameras unknown: matched pixels. Configurations kDegenerate, kUncalibrated
// or kPlanarOrPanoramic. Matches with non-finite coordinates are never
// inliers.
TwoViewGeometry EstimateUncalibratedTwoViewGeometry(
    const std::vector<Eigen::Vector2d>& points1,
    const std::vector<Eigen::Vector2d>& points2,
    const TwoViewGeometryOptions& options);

// Both cameras known: matched pixels of each camera (distortion is removed
// exactly). Any configuration.
TwoViewGeometry EstimateCalibratedTwoViewGeometry(
    const Camera& camera1, const std::vector<Eigen::Vector2d>& points1,
    const Camera& camera2, const std::vector<Eigen::Vector2d>& points2,
    const TwoViewGeometryOptions& options);

// The pinhole part [f 0 cx; 0 f cy; 0 0 1] of a camera.
Eigen::Matrix3d CalibrationMatrix(const Camera& camera);

}  // namespace flysfm
