#include "geometry/estimators.h"

#include <algorithm>

#include "geometry/absolute_pose.h"
#include "geometry/essential_matrix.h"

namespace flysfm {
namespace {

void Gather(const std::vector<Eigen::Vector2d>& points1,
            const std::vector<Eigen::Vector2d>& points2,
            const std::vector<int>& indices, std::vector<Eigen::Vector2d>* out1,
            std::vector<Eigen::Vector2d>* out2) {
  out1->resize(indices.size());
  out2->resize(indices.size());
  for (std::size_t k = 0; k < indices.size(); ++k) {
    (*out1)[k] = points1[indices[k]];
    (*out2)[k] = points2[indices[k]];
  }
}

bool RefitLinear(const std::vector<Eigen::Matrix3d>& fits, Eigen::Matrix3d* model) {
  if (fits.empty()) return false;
  *model = fits.front();
  return true;
}

}  // namespace

// ---------------------------------------------------------------- F --

void FundamentalEstimator::MinimalSolve(const std::vector<int>& sample,
                                        std::vector<Model>* models) const {
  std::vector<Eigen::Vector2d> x1, x2;
  Gather(points1_, points2_, sample, &x1, &x2);
  *models = FundamentalFromSevenPoints(x1, x2);
}

void FundamentalEstimator::NonMinimalSolve(const std::vector<int>& indices,
                                           const Model&,
                                           std::vector<Model>* models) const {
  std::vector<Eigen::Vector2d> x1, x2;
  Gather(points1_, points2_, indices, &x1, &x2);
  *models = FundamentalFromEightPoints(x1, x2);
}

bool FundamentalEstimator::Refine(const std::vector<int>& inliers,
                                  Model* model) const {
  std::vector<Model> fits;
  NonMinimalSolve(inliers, *model, &fits);
  return RefitLinear(fits, model);
}

// ---------------------------------------------------------------- H --

void HomographyEstimator::MinimalSolve(const std::vector<int>& sample,
                                       std::vector<Model>* models) const {
  std::vector<Eigen::Vector2d> x1, x2;
  Gather(points1_, points2_, sample, &x1, &x2);
  *models = HomographyFromPoints(x1, x2);
}

void HomographyEstimator::NonMinimalSolve(const std::vector<int>& indices,
                                          const Model&,
                                          std::vector<Model>* models) const {
  std::vector<Eigen::Vector2d> x1, x2;
  Gather(points1_, points2_, indices, &x1, &x2);
  *models = HomographyFromPoints(x1, x2);
}

bool HomographyEstimator::Refine(const std::vector<int>& inliers,
                                 Model* model) const {
  std::vector<Model> fits;
  NonMinimalSolve(inliers, *model, &fits);
  return RefitLinear(fits, model);
}

// ---------------------------------------------------------------- E --

void EssentialEstimator::MinimalSolve(const std::vector<int>& sample,
                                      std::vector<Model>* models) const {
  std::vector<Eigen::Vector2d> x1, x2;
  Gather(points1_, points2_, sample, &x1, &x2);
  *models = EssentialFromFivePoints(x1, x2);
}

void EssentialEstimator::NonMinimalSolve(const std::vector<int>& indices,
                                         const Model&,
                                         std::vector<Model>* models) const {
  std::vector<Eigen::Vector2d> x1, x2;
  Gather(points1_, points2_, indices, &x1, &x2);
  *models = EssentialFromFivePoints(x1, x2);
}

bool EssentialEstimator::Refine(const std::vector<int>& inliers,
                                Model* model) const {
  std::vector<Eigen::Vector2d> x1, x2;
  Gather(points1_, points2_, inliers, &x1, &x2);
  // Cheirality is decided by a majority: an even subset of at most 100
  // inliers decides it as well as all of them, at a fraction of the cost.
  std::vector<Eigen::Vector2d> s1, s2;
  const std::size_t stride = std::max<std::size_t>(1, x1.size() / 100);
  for (std::size_t k = 0; k < x1.size(); k += stride) {
    s1.push_back(x1[k]);
    s2.push_back(x2[k]);
  }
  Rigid3d cam2_from_cam1;
  if (RelativePoseFromEssential(*model, s1, s2, &cam2_from_cam1) == 0) {
    return false;
  }
  if (!RefineRelativePose(x1, x2, {}, &cam2_from_cam1, 10)) return false;
  *model = EssentialFromPose(cam2_from_cam1);
  return true;
}

// ------------------------------------------------------- absolute pose --

void AbsolutePoseEstimator::MinimalSolve(const std::vector<int>& sample,
                                         std::vector<Model>* models) const {
  std::vector<Eigen::Vector2d> x(3);
  std::vector<Eigen::Vector3d> X(3);
  for (int k = 0; k < 3; ++k) {
    x[k] = points2D_[sample[k]];
    X[k] = points3D_[sample[k]];
  }
  models->clear();
  for (const Rigid3d& pose : P3P(x, X)) models->push_back(pose.ToMatrix());
}

void AbsolutePoseEstimator::NonMinimalSolve(const std::vector<int>& indices,
                                            const Model& initial,
                                            std::vector<Model>* models) const {
  std::vector<Eigen::Vector2d> x(indices.size());
  std::vector<Eigen::Vector3d> X(indices.size());
  for (std::size_t k = 0; k < indices.size(); ++k) {
    x[k] = points2D_[indices[k]];
    X[k] = points3D_[indices[k]];
  }
  models->clear();
  for (Rigid3d pose : EPnP(x, X)) {
    RefineAbsolutePose(x, X, {}, &pose, 5);
    models->push_back(pose.ToMatrix());
  }
  Rigid3d pose = ToRigid(initial);
  if (RefineAbsolutePose(x, X, {}, &pose, 5)) models->push_back(pose.ToMatrix());
}

bool AbsolutePoseEstimator::Refine(const std::vector<int>& inliers,
                                   Model* model) const {
  Rigid3d pose = ToRigid(*model);
  if (!RefineAbsolutePose(points2D_, points3D_, inliers, &pose)) return false;
  *model = pose.ToMatrix();
  return true;
}

}  // namespace flysfm
