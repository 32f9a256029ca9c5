#pragma once

// Essential matrix: x2^T E x1 = 0 for normalized image coordinates
// (x/z, y/z, 1) of a match, E = [t]x R for cam2_from_cam1 = (R, t).

#include <vector>

#include <Eigen/Core>

#include "geometry/rigid3d.h"

namespace flysfm {

// The 5-point algorithm (Stewenius, Engels and Nister 2006): the four-
// dimensional null space of the epipolar constraints, the ten cubic
// constraints det(E) = 0 and 2 E E^T E - tr(E E^T) E = 0 reduced by
// Gauss-Jordan elimination in graded reverse lexicographic order, and the
// eigenvectors of the 10x10 action matrix. n >= 5 matches (for n > 5 the null
// space is the least-squares one). Up to 10 solutions of unit Frobenius norm;
// none for degenerate input (too few or unequal numbers of points, non-finite
// values, rank-deficient constraints).
std::vector<Eigen::Matrix3d> EssentialFromFivePoints(
    const std::vector<Eigen::Vector2d>& points1,
    const std::vector<Eigen::Vector2d>& points2);

// E = [t]x R.
Eigen::Matrix3d EssentialFromPose(const Rigid3d& cam2_from_cam1);

// The two rotations and the translation direction (unit) of E = [t]x R: the
// four poses (R1, t), (R1, -t), (R2, t), (R2, -t).
void DecomposeEssentialMatrix(const Eigen::Matrix3d& E, Eigen::Matrix3d* R1,
                              Eigen::Matrix3d* R2, Eigen::Vector3d* t);

// Relative pose from E by cheirality: of the four decompositions, the one that
// puts the most matches in front of both cameras (and closer than
// `max_depth` times the unit baseline), as voted by an even subset of at most
// 100 matches. Returns the number of all matches in front under it (0:
// no valid pose, *cam2_from_cam1 untouched). `points3D`, if given, receives
// the triangulated points in camera-1 coordinates and `in_front` their flags,
// one per match.
int RelativePoseFromEssential(const Eigen::Matrix3d& E,
                              const std::vector<Eigen::Vector2d>& points1,
                              const std::vector<Eigen::Vector2d>& points2,
                              Rigid3d* cam2_from_cam1,
                              std::vector<Eigen::Vector3d>* points3D = nullptr,
                              std::vector<char>* in_front = nullptr,
                              double max_depth = 1000.0);

// Levenberg-Marquardt on the Sampson error (normalized coordinates) of the
// matches at `indices` (all when empty), over the rotation and the direction
// of the translation (|t| = 1). Returns false, leaving the pose unchanged,
// when it cannot reduce the error.
bool RefineRelativePose(const std::vector<Eigen::Vector2d>& points1,
                        const std::vector<Eigen::Vector2d>& points2,
                        const std::vector<int>& indices, Rigid3d* cam2_from_cam1,
                        int max_iterations = 20);

}  // namespace flysfm
