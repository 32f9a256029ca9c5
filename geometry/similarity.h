#pragma once

// Least-squares alignment of corresponding 3D point sets (Umeyama 1991).

#include <optional>
#include <vector>

#include <Eigen/Core>

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

}  // namespace flysfm
