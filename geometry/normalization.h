#pragma once

// Hartley's isotropic normalization of 2D points, shared by the linear
// two-view solvers.

#include <vector>

#include <Eigen/Core>

namespace flysfm {

// Finds T (a similarity) moving the points' centroid to the origin with mean
// distance sqrt(2) from it, and writes T * point for each point. Returns
// false when the points are not all finite or coincide (no scale).
bool NormalizePoints(const std::vector<Eigen::Vector2d>& points,
                     std::vector<Eigen::Vector2d>* normalized,
                     Eigen::Matrix3d* transform);

// True when every coordinate of every point is finite.
bool AllFinite(const std::vector<Eigen::Vector2d>& points);
bool AllFinite(const std::vector<Eigen::Vector3d>& points);

}  // namespace flysfm
