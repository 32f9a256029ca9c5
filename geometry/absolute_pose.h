#pragma once

// Absolute pose (camera from world) from 2D-3D correspondences: a minimal
// P3P solver for RANSAC samples, EPnP for n >= 4, a Levenberg-Marquardt
// refinement, and RANSAC over all of them.

#include <vector>

#include <Eigen/Core>

#include "geometry/camera.h"
#include "geometry/ransac.h"
#include "geometry/rigid3d.h"

namespace flysfm {

// P3P (Grunert's formulation: the law of cosines on the three rays reduced to
// a quartic in the ratio of two depths). `points2D` are normalized image
// coordinates (x/z, y/z), exactly three, matched with three world points. Up
// to four poses cam_from_world with every point in front of the camera; none
// for non-finite input, coincident or collinear world points, or repeated
// rays.
std::vector<Rigid3d> P3P(const std::vector<Eigen::Vector2d>& points2D,
                         const std::vector<Eigen::Vector3d>& points3D);

// EPnP (Lepetit, Moreno-Noguer and Fua 2009), n >= 4 correspondences in
// normalized image coordinates: world points expressed in four control points
// (centroid and principal axes), the control points' camera coordinates from
// the null space of the 2n x 12 system with the three beta approximations of
// the paper, each refined by Gauss-Newton, and the pose with the smallest
// reprojection error. At most one solution; none for non-finite input, fewer
// than 4 points, or world points that are (nearly) coplanar or collinear
// (the 4-control-point parameterisation needs 3D spread: RANSAC pairs P3P
// with a non-linear refinement for planar scenes).
std::vector<Rigid3d> EPnP(const std::vector<Eigen::Vector2d>& points2D,
                          const std::vector<Eigen::Vector3d>& points3D);

// Levenberg-Marquardt on the squared reprojection error in normalized image
// coordinates over the correspondences at `indices` (all when empty).
// Returns false, leaving the pose unchanged, when it cannot reduce the error
// (too few points, a point behind the camera, non-finite values).
bool RefineAbsolutePose(const std::vector<Eigen::Vector2d>& points2D,
                        const std::vector<Eigen::Vector3d>& points3D,
                        const std::vector<int>& indices, Rigid3d* cam_from_world,
                        int max_iterations = 20);

struct AbsolutePoseOptions {
  // Inlier threshold on the reprojection error, in pixels (converted to the
  // normalized image plane with the camera's mean focal length).
  double max_error_px = 4.0;
  // A pose needs at least this many inliers (>= 3).
  int min_num_inliers = 12;
  // Levenberg-Marquardt refinement of the final pose on its inliers.
  bool refine = true;
  // ransac.max_error is derived from max_error_px.
  RansacOptions ransac;

  // True when every option is in its documented range; the functions taking
  // these options throw std::invalid_argument naming the bad one otherwise.
  bool Check() const;
};

struct AbsolutePoseResult {
  bool success = false;
  Rigid3d cam_from_world;
  std::vector<char> inlier_mask;
  int num_inliers = 0;
  int num_iterations = 0;
};

// RANSAC with P3P samples, LO by EPnP plus Levenberg-Marquardt on the
// inliers, and a final refinement. `pixels` are observed pixels of `camera`
// (distortion is removed exactly), `points3D` the matched world points.
// Correspondences with non-finite values are never inliers.
AbsolutePoseResult EstimateAbsolutePose(const Camera& camera,
                                        const std::vector<Eigen::Vector2d>& pixels,
                                        const std::vector<Eigen::Vector3d>& points3D,
                                        const AbsolutePoseOptions& options);

// The pose again from a longer list of correspondences whose first ones gave
// `first` (LSM densification appends some): RANSAC as EstimateAbsolutePose;
// where that fails, `first` is kept with its inliers over the whole list, by
// the same threshold. Either way the result has one inlier flag per
// correspondence, and succeeds.
AbsolutePoseResult ReestimateAbsolutePose(const Camera& camera,
                                          const std::vector<Eigen::Vector2d>& pixels,
                                          const std::vector<Eigen::Vector3d>& points3D,
                                          const Rigid3d& first,
                                          const AbsolutePoseOptions& options);

}  // namespace flysfm
