#pragma once

// Estimators for the generic Ransac() of ransac.h: fundamental matrix,
// homography, essential matrix and absolute pose. Each keeps references to
// its data, which must outlive it.

#include <limits>
#include <vector>

#include <Eigen/Core>

#include "geometry/fundamental_matrix.h"
#include "geometry/homography_matrix.h"
#include "geometry/rigid3d.h"
#include "geometry/types.h"

namespace flysfm {

// What the two-view estimators share: the matches, points1[i] <-> points2[i],
// held by reference for the duration of a RANSAC run.
class TwoViewData {
 public:
  TwoViewData(const std::vector<Eigen::Vector2d>& points1,
              const std::vector<Eigen::Vector2d>& points2)
      : points1_(points1), points2_(points2) {}
  int NumData() const { return static_cast<int>(points1_.size()); }

 protected:
  const std::vector<Eigen::Vector2d>& points1_;
  const std::vector<Eigen::Vector2d>& points2_;
};

// F from matches in pixels: 7-point samples, normalized 8-point least squares
// for LO, error = Sampson distance (pixels).
class FundamentalEstimator : public TwoViewData {
 public:
  using TwoViewData::TwoViewData;
  using Model = Eigen::Matrix3d;
  static constexpr int kMinSampleSize = 7;

  void MinimalSolve(const std::vector<int>& sample, std::vector<Model>* models) const;
  void NonMinimalSolve(const std::vector<int>& indices, const Model& initial,
                       std::vector<Model>* models) const;
  bool Refine(const std::vector<int>& inliers, Model* model) const;
  double SquaredError(const Model& F, int i) const {
    return FundamentalSampsonError(F, points1_[i], points2_[i]);
  }
};

// H from matches: 4-point DLT samples, DLT least squares for LO and a
// Levenberg-Marquardt refinement, error = Sampson distance (units of the
// points).
class HomographyEstimator : public TwoViewData {
 public:
  using TwoViewData::TwoViewData;
  using Model = Eigen::Matrix3d;
  static constexpr int kMinSampleSize = 4;

  void MinimalSolve(const std::vector<int>& sample, std::vector<Model>* models) const;
  void NonMinimalSolve(const std::vector<int>& indices, const Model& initial,
                       std::vector<Model>* models) const;
  bool Refine(const std::vector<int>& inliers, Model* model) const;
  double SquaredError(const Model& H, int i) const {
    return HomographySampsonError(H, points1_[i], points2_[i]);
  }
};

// E from matches in normalized image coordinates: 5-point samples, 5-point
// least squares for LO, a Levenberg-Marquardt refinement of the relative
// pose on the Sampson error, error = Sampson distance (normalized units).
class EssentialEstimator : public TwoViewData {
 public:
  using TwoViewData::TwoViewData;
  using Model = Eigen::Matrix3d;
  static constexpr int kMinSampleSize = 5;

  void MinimalSolve(const std::vector<int>& sample, std::vector<Model>* models) const;
  void NonMinimalSolve(const std::vector<int>& indices, const Model& initial,
                       std::vector<Model>* models) const;
  bool Refine(const std::vector<int>& inliers, Model* model) const;
  double SquaredError(const Model& E, int i) const {
    return FundamentalSampsonError(E, points1_[i], points2_[i]);
  }
};

// cam_from_world [R | t] from normalized image points and world points: P3P
// samples, EPnP plus Levenberg-Marquardt for LO, Levenberg-Marquardt
// refinement, error = reprojection error in the normalized image plane
// (+inf behind the camera or for non-finite data).
class AbsolutePoseEstimator {
 public:
  using Model = Matrix3x4d;
  static constexpr int kMinSampleSize = 3;

  AbsolutePoseEstimator(const std::vector<Eigen::Vector2d>& points2D,
                        const std::vector<Eigen::Vector3d>& points3D)
      : points2D_(points2D), points3D_(points3D) {}

  static Rigid3d ToRigid(const Matrix3x4d& matrix) {
    return Rigid3d(Eigen::Matrix3d(matrix.leftCols<3>()), matrix.col(3));
  }

  int NumData() const { return static_cast<int>(points2D_.size()); }
  void MinimalSolve(const std::vector<int>& sample, std::vector<Model>* models) const;
  void NonMinimalSolve(const std::vector<int>& indices, const Model& initial,
                       std::vector<Model>* models) const;
  bool Refine(const std::vector<int>& inliers, Model* model) const;
  double SquaredError(const Model& P, int i) const {
    const Eigen::Vector3d& X = points3D_[i];
    const double z = P(2, 0) * X.x() + P(2, 1) * X.y() + P(2, 2) * X.z() + P(2, 3);
    if (!(z > std::numeric_limits<double>::epsilon())) {
      return std::numeric_limits<double>::infinity();
    }
    const double x = P(0, 0) * X.x() + P(0, 1) * X.y() + P(0, 2) * X.z() + P(0, 3);
    const double y = P(1, 0) * X.x() + P(1, 1) * X.y() + P(1, 2) * X.z() + P(1, 3);
    const double dx = x / z - points2D_[i].x();
    const double dy = y / z - points2D_[i].y();
    return dx * dx + dy * dy;
  }

 private:
  const std::vector<Eigen::Vector2d>& points2D_;
  const std::vector<Eigen::Vector3d>& points3D_;
};

}  // namespace flysfm
