#pragma once

// Bundle adjustment of the scene: the bridge between Reconstruction and the
// bundle module's own problem description. A local problem is built from the
// images concerned only, so its cost does not grow with the model.

#include <unordered_map>
#include <vector>

#include "bundle/bundle_adjuster.h"
#include "core/scene/reconstruction.h"

namespace flysfm {

struct SceneBundleResult {
  BundleAdjuster::Summary summary;
  // The points the solve could move (seen by a refined image).
  std::vector<point3D_t> points;
};

// Refines the images of `weights` (image id -> the paper's Eq. 4 weight p;
// infinity = held constant) and every point they observe. Other registered
// images that see those points enter with constant poses, up to
// `max_constant_observers` per point in track order (0: all): a point seen
// from a few fixed views is pinned as well as from dozens, and in a video the
// dozens would dominate the cost of the solve.
SceneBundleResult AdjustLocalBundle(
    const std::unordered_map<image_t, double>& weights,
    const BundleAdjuster::Options& options, int max_constant_observers,
    Reconstruction* reconstruction);

// Every registered image and point, weight 1 (the gauge as the options say).
SceneBundleResult AdjustGlobalBundle(const BundleAdjuster::Options& options,
                                     Reconstruction* reconstruction);

// Data snooping, the last step of a photogrammetric adjustment: after a
// global BA, each image's noise is estimated from its own errors and the
// observations it makes improbable are dropped, then the poses and points are
// adjusted again without them. Image noise isotropic and Gaussian (sigma per
// coordinate) makes an error's length Rayleigh distributed: its median is
// sigma sqrt(2 ln 2), robust to the outliers themselves, and a share
// `quantile` of the inliers lies within sigma sqrt(-2 ln(1 - quantile)).
// Per image, not one sigma for the model: a blurred photo or a frame shaken
// during its readout is measured less precisely throughout, and keeps its
// observations. The cameras are held as the first BA left them: a camera
// model short of some of the lens' terms leaves systematic errors towards the
// image border, which the snooping would select away and the intrinsics would
// then follow (fr1_xyz without K, SIMPLE_RADIAL: focal 535 -> 544 px).
// Like Baarda's snooping it iterates: each adjustment moves every error a
// little and takes a few beyond their bound, and a model whose observations
// were dropped after its last adjustment is not the optimum of those it
// keeps (on a rendered session with exact ground truth one more BA took the
// cameras' error from 0.79 to 0.56 mm). So adjust and drop alternate until
// nothing is beyond its bound, or for `max_rounds` adjustments, with the
// bounds of the first estimate: estimated again each round, they would
// shrink with the tail each round removed and go on removing.
struct OutlierSnooping {
  // Per judged image with observations, the error beyond which they went.
  std::unordered_map<image_t, double> max_error_px;
  std::size_t num_removed = 0;
  int num_rounds = 0;  // adjustments made
  BundleAdjuster::Summary summary;  // of the last adjustment
};
// Over the images of `weights`, adjusted as AdjustLocalBundle adjusts them:
// only their own observations are judged (held images, weight infinity,
// are not), so that between shots the images a large model's refinement
// adjusts are snooped at the cost of their own BA (Engine::Refine). An
// adjustment that gives way to `options.should_stop` ends the snooping.
OutlierSnooping SnoopOutliers(const std::unordered_map<image_t, double>& weights,
                              int max_constant_observers, double quantile, int max_rounds,
                              BundleAdjuster::Options options, double min_angle_deg,
                              Reconstruction* reconstruction);
// Over every registered image, each adjustment a global BA.
OutlierSnooping SnoopOutliers(double quantile, int max_rounds,
                              const BundleAdjuster::Options& options, double min_angle_deg,
                              Reconstruction* reconstruction);

}  // namespace flysfm
