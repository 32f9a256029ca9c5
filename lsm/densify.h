#pragma once

// LSM densification (the paper's Sect. III-C-3): 3D points that a newly
// registered image should see but has no observation of are projected with
// its initial pose and their 2D positions found by LSM against the
// reference observation with the closest viewing direction. Accepted
// results are new 2D-3D correspondences for the pose re-estimation.

#include <vector>

#include <Eigen/Core>

#include "geometry/camera.h"
#include "geometry/rigid3d.h"
#include "lsm/lsm.h"

namespace flysfm {

// An image prepared for densification: its LSM pyramid (BuildLsmPyramid,
// at least DensifyOptions::num_pyramid_levels levels), camera and pose.
// 2D positions are the camera's pixel coordinates, which must follow
// OpenCV's convention (pixel (c, r) shows image point (c, r)), as LSM does.
struct LsmView {
  std::vector<LsmImage> pyramid;
  Camera camera;
  Rigid3d cam_from_world;
};

struct DensifyObservation {
  int view = -1;  // index into the reference views
  Eigen::Vector2d point2D = Eigen::Vector2d::Zero();
};

// A 3D point with its observations in registered (reference) images.
struct DensifyCandidate {
  Eigen::Vector3d xyz = Eigen::Vector3d::Zero();
  std::vector<DensifyObservation> observations;
};

struct DensifyOptions {
  // The final, full-resolution LSM, whose tests accept or reject a point.
  LsmOptions lsm;
  // Coarse-to-fine levels: the start error of a point is the initial pose's
  // error projected, several pixels for a degree (1 deg at a 500 px focal
  // length is 9 px), beyond a 15x15 window's basin at full resolution.
  // Levels num_pyramid_levels - 1 .. 1 estimate every point coarsely; the
  // initial pose is corrected to the consensus of those estimates (robust
  // Gauss-Newton on the reprojection error), and full-resolution LSM starts
  // from the corrected pose's projection and decides. 1 disables this.
  int num_pyramid_levels = 3;
  // Largest distance of the accepted position from the reprojection
  // (pixels): the pose error the densification tolerates.
  double max_displacement_px = 16.0;
  // Start the affine part of the window from the map between the two views
  // induced by a plane through the point, fronto-parallel to the reference
  // camera; identity otherwise.
  bool predict_affine = true;
  // Candidates must lie at least this far in front of the new camera,
  // relative to their distance: grazing or behind-camera points are skipped.
  double min_depth = 1e-6;

  bool Check() const;
};

struct DensifyMatch {
  int candidate = -1;
  int reference_view = -1;
  Eigen::Vector2d point2D = Eigen::Vector2d::Zero();  // in the new image
  LsmResult lsm;  // the full-resolution result
};

struct DensifyResult {
  std::vector<DensifyMatch> matches;  // accepted, in candidate order
  int num_candidates = 0;
  int num_behind = 0;          // behind the new camera
  int num_outside = 0;         // projected outside the new image
  int num_no_reference = 0;    // no reference observation whose window fits
  int num_displaced = 0;       // converged beyond max_displacement_px
  LsmStatusCounts lsm_counts;  // full-resolution outcomes of attempted points
};

// `image` is the new image with its initial pose; `references` the
// registered views the candidates' observations index. Throws
// std::invalid_argument on invalid options, a pyramid with too few levels or
// an observation naming no reference view.
DensifyResult Densify(const LsmView& image,
                      const std::vector<LsmView>& references,
                      const std::vector<DensifyCandidate>& candidates,
                      const DensifyOptions& options = DensifyOptions());

// Local affine map (new-image pixels per reference pixel) at `reference_point`
// induced by the plane through `xyz` fronto-parallel to the reference camera;
// by central differences, so that lens distortion is included.
Eigen::Matrix2d PredictAffine(const LsmView& reference,
                              const Eigen::Vector2d& reference_point,
                              const Eigen::Vector3d& xyz, const LsmView& image);

}  // namespace flysfm
