#pragma once

// The measures photogrammetry practice judges a model by, per 3D point and
// per registered image, as plain functions (docs/quality.md):
//   point: observing images, largest triangulation angle, mean reprojection
//          error, and the largest standard deviation of its position with the
//          poses and intrinsics held;
//   image: 2D-3D inliers, the share of the image their convex hull covers,
//          and the largest standard deviation of its projection centre with
//          the points and intrinsics held.
// Both uncertainties are first order: the covariance sigma^2 (J^T J)^-1 of a
// least-squares fit with independent pixel noise of standard deviation sigma
// on each coordinate. A configuration that does not determine the unknowns
// (one view, parallel rays, too few or collinear points) has no finite
// covariance: it is reported as nullopt, never as a number.

#include <optional>
#include <vector>

#include <Eigen/Core>

#include "core/scene/reconstruction.h"
#include "geometry/camera.h"
#include "geometry/rigid3d.h"

namespace flysfm {

// d pixel / d point_in_cam of Camera::ImgFromCam, 2x3, by central differences
// (every COLMAP model, distortion included, without one derivative per
// model). nullopt for a point not in front of the camera.
std::optional<Eigen::Matrix<double, 2, 3>> ProjectionJacobian(const Camera& camera,
                                                              const Eigen::Vector3d& in_cam);

// One image observing a point: its pose and intrinsics.
struct PointView {
  Rigid3d cam_from_world;
  const Camera* camera = nullptr;
};

// One view's share of a point's information for 1 px of noise, J^T J with
// J = d pixel / d xyz (2x3); nullopt when the point is not in front of it.
// A point's information is the sum over its views.
std::optional<Eigen::Matrix3d> ViewInformation(const Eigen::Vector3d& xyz, const PointView& view);

// sigma_px^2 information^-1 (information for 1 px), nullopt when it is
// singular as PointCovariance says.
std::optional<Eigen::Matrix3d> CovarianceFromInformation(const Eigen::Matrix3d& information,
                                                         double sigma_px);

// The point's 3x3 covariance, poses and intrinsics held: sigma_px^2
// (sum_i J_i^T J_i)^-1, J_i = d pixel_i / d xyz. nullopt for fewer than two
// views, a view the point is not in front of, or rays too close to parallel
// for the sum to be inverted (its smallest eigenvalue below 1e-12 of its
// largest: rays within about 1e-4 degrees).
std::optional<Eigen::Matrix3d> PointCovariance(const Eigen::Vector3d& xyz,
                                               const std::vector<PointView>& views,
                                               double sigma_px);

// The camera's 6x6 covariance, points and intrinsics held, in the
// parametrisation in_cam = exp([omega]x) R (X - C): omega (a rotation in the
// camera frame, radians) first, then the projection centre C in model units,
// so that the lower right 3x3 block is the centre's covariance. nullopt for
// fewer than 3 points, a point not in front of the camera, or a
// configuration that does not fix the pose (all points on one ray): the
// information matrix, scaled to a unit diagonal, has an eigenvalue below
// 1e-12.
std::optional<Eigen::Matrix<double, 6, 6>> PoseCovariance(
    const Rigid3d& cam_from_world, const Camera& camera,
    const std::vector<Eigen::Vector3d>& points, double sigma_px);

// The square root of a covariance's largest eigenvalue: the standard
// deviation along the worst direction.
double LargestStdDev(const Eigen::Matrix3d& covariance);

// The angle in radians between two rays (any lengths): atan2 of |a x b| and
// a.b, exact near 0, where acos of a dot product loses half the digits.
double RayAngle(const Eigen::Vector3d& a, const Eigen::Vector3d& b);

// The largest angle in degrees between the rays from `centers` to `xyz`
// (0 for fewer than two).
double MaxTriangulationAngleDeg(const Eigen::Vector3d& xyz,
                                const std::vector<Eigen::Vector3d>& centers);

// Area of the convex hull of `points` (0 for fewer than three or collinear).
double ConvexHullArea(std::vector<Eigen::Vector2d> points);

struct PointQuality {
  int views = 0;                // observing images
  double max_angle_deg = 0;     // largest triangulation angle
  double error_px = 0;          // mean reprojection error of its observations
  double squared_error_sum = 0; // px^2, over its observations (the model's RMS sums it)
  // Largest standard deviation of its position, model units, for the pixel
  // sigma it was measured with; nullopt when undefined.
  std::optional<double> sigma;
};

struct ImageQuality {
  int inliers = 0;      // observations of 3D points (2D-3D inliers)
  double spread = 0;    // convex hull of their keypoints / image area, in [0, 1]
  double squared_error_sum = 0;  // px^2, over those observations
  // Largest standard deviation of the projection centre, model units;
  // nullopt when undefined.
  std::optional<double> center_sigma;
};

// The measures of one point / one registered image of `reconstruction`, for
// pixel noise `sigma_px`. The reprojection error is the model's own
// (Reconstruction::ReprojectionError, rolling shutter included); the
// Jacobians use the static projection.
// `information`, when given, receives the point's information for 1 px
// (nullopt when a view has the point behind it): what an extension of its
// track adds to (QualityTracker).
PointQuality MeasurePoint(const Reconstruction& reconstruction, point3D_t point3D_id,
                          double sigma_px,
                          std::optional<Eigen::Matrix3d>* information = nullptr);
ImageQuality MeasureImage(const Reconstruction& reconstruction, image_t image_id,
                          double sigma_px);

}  // namespace flysfm
