#pragma once

// LSM densification (the paper's Sect. III-C-3): 3D points that a newly
// registered image should see but has no observation of are projected with
// its initial pose and their 2D positions found by LSM against their
// reference observations, the closest viewing direction first (see
// docs/lsm.md). Accepted results are new 2D-3D correspondences for the pose
// re-estimation.

#include <functional>
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
// A reference may instead be kept as windows around its points
// (core/lsm_image_store): `window` then gives the one a template needs, and
// `pyramid` stays empty.
struct LsmView {
  std::vector<LsmImage> pyramid;
  Camera camera;
  Rigid3d cam_from_world;
  // The window on pyramid `level` around the full-resolution `point` (an
  // LsmImage with an origin, in that level's pixels), holding at least
  // LsmTemplateReach pixels around it, and DensifyOptions::window_shift_px
  // more on level 0; empty when the view has no pixels there.
  std::function<LsmImage(int level, const Eigen::Vector2d& point)> window;

  // The image that holds the template around `point` on `level`.
  LsmImage Template(int level, const Eigen::Vector2d& point) const {
    return pyramid.empty() ? window(level, point) : pyramid[level];
  }
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
  // Reference observations tried per point at full resolution, closest
  // viewing direction first, until one is accepted: a window that fails from
  // one reference (an occluding edge beside the point there, a slant the
  // fronto-parallel prediction misses) often matches from another.
  int max_references_per_point = 3;
  // When no centred window is accepted, windows shifted by this much
  // (pixels) along the image axes and diagonals are tried: one on the
  // point's side of a depth edge, or reaching texture beside a flat patch,
  // often converges. At most the window's radius (larger values are
  // clamped), so that the point stays inside the window; its match follows
  // from the window's affine map. 0 disables.
  double window_shift_px = 7.0;
  // A converged window is accepted only if its sigma0 is at most this many
  // times the median sigma0 of the image's centred windows: a window
  // straddling two surfaces (or, shifted, reaching an occluder) converges
  // to a compromise of the two motions and leaves a residual several times
  // that of a window on one surface. With fewer than 10 converged centred
  // windows there is no median: no bound, and no shifted windows.
  double max_relative_sigma0 = 3.0;
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
  int num_behind = 0;  // behind the new camera
  // Projected outside the new image: beyond max_displacement_px with the
  // initial pose, or at all with the corrected one.
  int num_outside = 0;
  int num_no_reference = 0;  // no reference observation whose window fits
  int num_displaced = 0;     // converged beyond max_displacement_px
  int num_imprecise = 0;     // converged only above the sigma0 bound
  // Full-resolution outcomes of the attempted points not counted as
  // imprecise: of the accepted window, else of the last one tried.
  LsmStatusCounts lsm_counts;
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
