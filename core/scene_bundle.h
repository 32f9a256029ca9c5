#pragma once

// Bundle adjustment of the scene: the bridge between Reconstruction and the
// bundle module's own problem description. A local problem is built from the
// images concerned only, so its cost does not grow with the model.

#include <unordered_map>
#include <vector>

#include "bundle/bundle_adjuster.h"
#include "core/reconstruction.h"

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

}  // namespace flysfm
