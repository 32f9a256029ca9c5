#pragma once

// LSM refinement of the correspondences of one image pair (the paper's
// Sect. III-C-2): each match's position in image 2 is refined; a match that
// does not converge is an outlier.

#include <vector>

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "lsm/lsm.h"

namespace flysfm {

struct RefineMatchesResult {
  // One per input match, in input order; results[i].point2 is the refined
  // position where results[i].Converged().
  std::vector<LsmResult> results;
  // Indices of the converged matches: the inliers to keep.
  std::vector<int> inliers;
  // Matches by final status (converged ones under kConverged).
  LsmStatusCounts counts;
};

// points1[i] in image 1 matches points2[i] in image 2 (OpenCV pixel
// convention). Throws std::invalid_argument when the lists differ in size or
// the options are invalid.
RefineMatchesResult RefineMatches(const LsmImage& image1,
                                  const LsmImage& image2,
                                  const std::vector<Eigen::Vector2d>& points1,
                                  const std::vector<Eigen::Vector2d>& points2,
                                  const LsmOptions& options = LsmOptions());

// The same with image 1 kept only as windows (LsmImage with an origin):
// windows1[i] holds points1[i]'s template, at least LsmTemplateReach pixels
// around it. Throws std::invalid_argument when the lists differ in size.
RefineMatchesResult RefineMatches(const std::vector<LsmImage>& windows1,
                                  const LsmImage& image2,
                                  const std::vector<Eigen::Vector2d>& points1,
                                  const std::vector<Eigen::Vector2d>& points2,
                                  const LsmOptions& options = LsmOptions());

// The same on grey images (CV_8U or CV_32F), each converted once.
RefineMatchesResult RefineMatches(const cv::Mat& image1, const cv::Mat& image2,
                                  const std::vector<Eigen::Vector2d>& points1,
                                  const std::vector<Eigen::Vector2d>& points2,
                                  const LsmOptions& options = LsmOptions());

}  // namespace flysfm
