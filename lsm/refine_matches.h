#pragma once

// LSM refinement of one SIFT match (the paper's Sect. III-C-2): the position
// of image 1's feature in image 2 is refined; a match that does not converge
// is an outlier. Each feature is matched on the pyramid level of its own
// scale, from the similarity of the two SIFT frames, then sharpened on full
// resolution.

#include <functional>
#include <vector>

#include <Eigen/Core>

#include "lsm/lsm.h"

namespace flysfm {

// What SIFT says of a feature: where, how large, which way.
struct FeatureFrame {
  Eigen::Vector2d xy = Eigen::Vector2d::Zero();  // full resolution, OpenCV convention
  // Diameter in full-resolution pixels (Keypoint::scale); 0: unknown, and
  // with it the magnification between the frames (LSM starts unscaled).
  double scale = 0;
  double orientation = 0;  // radians (Keypoint::orientation)
};

// A feature is matched on the coarsest of `num_levels` pyramid levels where
// its diameter is at least kFeatureScalePerWindow of the window. A feature
// SIFT found at a coarse scale is a blob that large; a 15-pixel window on
// full resolution sees a smooth part of it, too little texture to match (on
// 6 MP photos most of the largest-scale features), and a view from nearer
// magnifies it beyond the affine start's reach.
constexpr double kFeatureScalePerWindow = 0.4;
int FeatureLevel(double feature_scale, int window_size, int num_levels);

struct RefinedMatch {
  // LSM's status on the features' levels.
  LsmStatus status = LsmStatus::kInvalidInput;
  // Where converged: feature 1's match in image 2, full resolution.
  Eigen::Vector2d point2 = Eigen::Vector2d::Zero();

  bool Converged() const { return status == LsmStatus::kConverged; }
};

// Image 1's pixels on a pyramid level (level 0 full resolution, each next
// one cv::pyrDown's half) around feature 1: a whole level, or a window of at
// least LsmTemplateReach pixels around it (an LsmImage with an origin).
using TemplateOnLevel = std::function<LsmImage(int level)>;

// Refines feature 2's position as the match of feature 1, searching image 2's
// pyramid (BuildLsmPyramid). With the matcher's options.
RefinedMatch RefineMatch(const TemplateOnLevel& template1, const FeatureFrame& feature1,
                         const std::vector<LsmImage>& pyramid2, const FeatureFrame& feature2,
                         LsmMatcher* matcher);

}  // namespace flysfm
