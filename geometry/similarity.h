#pragma once

// Alignment of corresponding 3D point sets: least squares (Umeyama 1991),
// and RANSAC around it for correspondences with outliers, e.g. the matched
// points of two sub-models of a reconstruction that are to be merged.

#include <optional>
#include <vector>

#include <Eigen/Core>

#include "geometry/ransac.h"
#include "geometry/rigid3d.h"
#include "geometry/sim3d.h"

namespace flysfm {

// The similarity dst_from_src = (s, R, t) minimizing
// sum_i |dst_i - (s R src_i + t)|^2. n >= 3 pairs; no solution for unequal
// sizes, non-finite values, or source or destination points that are
// (nearly) collinear or coincident.
std::optional<Sim3d> SimilarityFromPoints(const std::vector<Eigen::Vector3d>& src,
                                          const std::vector<Eigen::Vector3d>& dst);

// The same without scale (s = 1): the rigid dst_from_src.
std::optional<Rigid3d> RigidFromPoints(const std::vector<Eigen::Vector3d>& src,
                                       const std::vector<Eigen::Vector3d>& dst);

// The similarity dst_from_src from correspondences src[i] <-> dst[i] with
// outliers: LO-RANSAC on 3-point samples, each fitted by
// SimilarityFromPoints, which also fits the inliers. The error of a pair is
// |dst_i - S src_i|, so options.max_error is a distance in dst units: it
// keeps one meaning whatever the scale, and src noise counts scaled by S (pass
// as dst the model whose units the threshold is in). The winner is in effect
// the largest consistent subset: a smaller self-consistent wrong one (matches
// to a repeated structure) loses to the true one, but a larger one would win,
// so a caller merging models should still judge the inlier count.
// Unequal sizes, fewer than 3 pairs or only degenerate samples (collinear or
// coincident points) give success = false; invalid options throw
// std::invalid_argument.
RansacResult<Sim3d> EstimateSimilarity(const std::vector<Eigen::Vector3d>& src,
                                       const std::vector<Eigen::Vector3d>& dst,
                                       const RansacOptions& options);

}  // namespace flysfm
