#pragma once

// Triangulation of 3D points from two or more views: linear DLT solvers and a
// RANSAC multi-view triangulation that tolerates outlier observations.

#include <optional>
#include <vector>

#include <Eigen/Core>

#include "geometry/camera.h"
#include "geometry/ransac.h"
#include "geometry/rigid3d.h"
#include "geometry/types.h"

namespace flysfm {

// Two-view DLT: the point X (world coordinates) with point1 ~ cam1_from_world X
// and point2 ~ cam2_from_world X, where point1 and point2 are normalized image
// coordinates (x/z, y/z). No solution for non-finite input, coinciding rays
// (zero baseline along the ray) or a point at infinity.
std::optional<Eigen::Vector3d> TriangulatePoint(const Matrix3x4d& cam1_from_world,
                                                const Matrix3x4d& cam2_from_world,
                                                const Eigen::Vector2d& point1,
                                                const Eigen::Vector2d& point2);

// Multi-view DLT over n >= 2 views (least squares), same conventions.
std::optional<Eigen::Vector3d> TriangulateMultiViewPoint(
    const std::vector<Matrix3x4d>& cams_from_world,
    const std::vector<Eigen::Vector2d>& points);

// Angle in degrees at `point` between the rays to the two camera centres.
double TriangulationAngleDeg(const Eigen::Vector3d& center1,
                             const Eigen::Vector3d& center2,
                             const Eigen::Vector3d& point);

// Depth of the point in the camera (z in camera coordinates) is positive.
bool HasPositiveDepth(const Matrix3x4d& cam_from_world,
                      const Eigen::Vector3d& point);

// One observation of a point for RANSAC triangulation: the observing image's
// pose, its camera and the observed pixel.
struct TriangulationObservation {
  Rigid3d cam_from_world;
  const Camera* camera = nullptr;
  Eigen::Vector2d pixel = Eigen::Vector2d::Zero();
};

struct TriangulationOptions {
  // An observation is an inlier when the point reprojects within this many
  // pixels of it (and lies in front of its camera).
  double max_error_px = 2.0;
  // Every minimal sample, and the final inlier set, must see the point under
  // at least this angle (degrees) between two of its rays.
  double min_tri_angle_deg = 1.5;
  // At least this many inlier observations (>= 2).
  int min_num_inliers = 2;
  // Gauss-Newton refinement of the point on its inliers' pixel errors.
  bool refine = true;
  // ransac.max_error is taken from max_error_px. A track has a few to a few
  // tens of observations, so a few hundred pair samples cover it; without a
  // bound, a point whose rays are all nearly parallel (adjacent video
  // frames) would draw the RANSAC maximum.
  RansacOptions ransac = [] {
    RansacOptions options;
    options.max_iterations = 200;
    return options;
  }();

  // True when every option is in its documented range; the functions taking
  // these options throw std::invalid_argument naming the bad one otherwise.
  bool Check() const;
};

struct TriangulationResult {
  bool success = false;
  Eigen::Vector3d point = Eigen::Vector3d::Zero();
  std::vector<char> inlier_mask;
  int num_inliers = 0;
};

// RANSAC multi-view triangulation: samples pairs of observations,
// triangulates each pair (DLT) and keeps it only when the point is in front
// of both cameras and seen under min_tri_angle_deg; scores by reprojection
// error in pixels over all observations; the best consensus set is
// re-triangulated from all its inliers and refined. Observations with no
// camera or a non-finite pixel never count as inliers.
TriangulationResult EstimateTriangulation(
    const std::vector<TriangulationObservation>& observations,
    const TriangulationOptions& options);

}  // namespace flysfm
