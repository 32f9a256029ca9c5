#include "geometry/triangulation.h"

#include <cmath>
#include <stdexcept>
#include <string>

#include <Eigen/Dense>

namespace flysfm {
namespace {

// Of the squared singular values: a second (near-)zero one means the rays
// coincide and the point is anywhere on them. 1e-14 is well above the
// round-off of A^T A (1e-16 of its largest eigenvalue).
constexpr double kRankTolerance = 1e-14;

// The DLT's point: the right singular vector of the smallest singular value
// of A (two rows per view), taken as the eigenvector of the smallest
// eigenvalue of `normal` = A^T A. A^T A is 4x4 whatever the
// number of views, and its eigen-decomposition costs half a 4x4 SVD, which
// RANSAC triangulation and the cheirality test of every verified pair call
// per match. Squaring the condition number costs nothing measurable here:
// the eigenvector's error is the round-off over the eigenvalue gap, 1e-10 at
// a 0.1 degree triangulation angle.
std::optional<Eigen::Vector3d> SolveDlt(const Eigen::Matrix4d& normal) {
  if (!normal.allFinite()) return std::nullopt;
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix4d> solver(normal);
  if (solver.info() != Eigen::Success) return std::nullopt;
  const Eigen::Vector4d& lambda = solver.eigenvalues();  // ascending
  if (!(lambda(1) > kRankTolerance * lambda(3))) return std::nullopt;
  const Eigen::Vector4d X = solver.eigenvectors().col(0);
  if (!(std::abs(X(3)) > 1e-12 * X.head<3>().norm())) return std::nullopt;
  const Eigen::Vector3d point = X.hnormalized();
  if (!point.allFinite()) return std::nullopt;
  return point;
}

// Pixel reprojection error of `point` in one observation; +inf behind the
// camera.
double SquaredReprojectionError(const TriangulationObservation& obs,
                                const Eigen::Vector3d& point) {
  const Eigen::Vector3d in_cam = obs.cam_from_world * point;
  if (!(in_cam.z() > std::numeric_limits<double>::epsilon())) {
    return std::numeric_limits<double>::infinity();
  }
  return (obs.camera->ImgFromCam(in_cam) - obs.pixel).squaredNorm();
}

class TriangulationEstimator {
 public:
  using Model = Eigen::Vector3d;
  static constexpr int kMinSampleSize = 2;

  TriangulationEstimator(const std::vector<TriangulationObservation>& observations,
                         const TriangulationOptions& options)
      : observations_(observations), options_(options) {
    const int n = static_cast<int>(observations.size());
    valid_.assign(n, 0);
    normalized_.resize(n);
    projections_.resize(n);
    centers_.resize(n);
    for (int i = 0; i < n; ++i) {
      const TriangulationObservation& obs = observations[i];
      projections_[i] = obs.cam_from_world.ToMatrix();
      centers_[i] = ProjectionCenter(obs.cam_from_world);
      if (obs.camera == nullptr || !obs.pixel.allFinite() ||
          !obs.camera->IsValid() || !projections_[i].allFinite()) {
        continue;
      }
      normalized_[i] = obs.camera->CamFromImg(obs.pixel);
      valid_[i] = normalized_[i].allFinite();
    }
  }

  int NumData() const { return static_cast<int>(observations_.size()); }

  void MinimalSolve(const std::vector<int>& sample,
                    std::vector<Model>* models) const {
    const int i = sample[0];
    const int j = sample[1];
    if (!valid_[i] || !valid_[j]) return;
    const auto point = TriangulatePoint(projections_[i], projections_[j],
                                        normalized_[i], normalized_[j]);
    if (!point) return;
    if (!HasPositiveDepth(projections_[i], *point) ||
        !HasPositiveDepth(projections_[j], *point)) {
      return;
    }
    if (TriangulationAngleDeg(centers_[i], centers_[j], *point) <
        options_.min_tri_angle_deg) {
      return;
    }
    models->push_back(*point);
  }

  void NonMinimalSolve(const std::vector<int>& indices, const Model&,
                       std::vector<Model>* models) const {
    std::vector<Matrix3x4d> projections;
    std::vector<Eigen::Vector2d> points;
    for (const int i : indices) {
      if (!valid_[i]) continue;
      projections.push_back(projections_[i]);
      points.push_back(normalized_[i]);
    }
    const auto point = TriangulateMultiViewPoint(projections, points);
    if (point) models->push_back(*point);
  }

  // Gauss-Newton on the pixel errors, Jacobian by central differences.
  bool Refine(const std::vector<int>& inliers, Model* model) const {
    if (!options_.refine) return false;
    Eigen::Vector3d x = *model;
    double cost = Cost(inliers, x);
    if (!std::isfinite(cost)) return false;
    const double initial_cost = cost;
    for (int iteration = 0; iteration < 10; ++iteration) {
      Eigen::Matrix3d JtJ = Eigen::Matrix3d::Zero();
      Eigen::Vector3d Jtr = Eigen::Vector3d::Zero();
      const double h = 1e-6 * std::max(1.0, x.norm());
      for (const int i : inliers) {
        const TriangulationObservation& obs = observations_[i];
        const Eigen::Vector3d in_cam = obs.cam_from_world * x;
        if (!(in_cam.z() > 0)) return false;
        const Eigen::Vector2d r = obs.camera->ImgFromCam(in_cam) - obs.pixel;
        Eigen::Matrix<double, 2, 3> J;
        for (int k = 0; k < 3; ++k) {
          Eigen::Vector3d step = Eigen::Vector3d::Zero();
          step(k) = h;
          const Eigen::Vector3d plus = obs.cam_from_world * (x + step);
          const Eigen::Vector3d minus = obs.cam_from_world * (x - step);
          J.col(k) = (obs.camera->ImgFromCam(plus) -
                      obs.camera->ImgFromCam(minus)) / (2 * h);
        }
        JtJ += J.transpose() * J;
        Jtr += J.transpose() * r;
      }
      const Eigen::Vector3d delta = JtJ.ldlt().solve(-Jtr);
      if (!delta.allFinite()) break;
      const Eigen::Vector3d candidate = x + delta;
      const double candidate_cost = Cost(inliers, candidate);
      if (!(candidate_cost < cost)) break;
      const bool converged = cost - candidate_cost < 1e-12 * (1.0 + cost);
      x = candidate;
      cost = candidate_cost;
      if (converged) break;
    }
    if (!(cost < initial_cost)) return false;
    *model = x;
    return true;
  }

  double SquaredError(const Model& point, int index) const {
    if (!valid_[index]) return std::numeric_limits<double>::infinity();
    return SquaredReprojectionError(observations_[index], point);
  }

  const Eigen::Vector3d& Center(int i) const { return centers_[i]; }

 private:
  double Cost(const std::vector<int>& indices, const Eigen::Vector3d& x) const {
    double cost = 0;
    for (const int i : indices) cost += SquaredError(x, i);
    return cost;
  }

  const std::vector<TriangulationObservation>& observations_;
  const TriangulationOptions& options_;
  std::vector<char> valid_;
  std::vector<Eigen::Vector2d> normalized_;
  std::vector<Matrix3x4d> projections_;
  std::vector<Eigen::Vector3d> centers_;
};

}  // namespace

std::optional<Eigen::Vector3d> TriangulatePoint(const Matrix3x4d& cam1_from_world,
                                                const Matrix3x4d& cam2_from_world,
                                                const Eigen::Vector2d& point1,
                                                const Eigen::Vector2d& point2) {
  Eigen::Matrix4d A;
  A.row(0) = point1.x() * cam1_from_world.row(2) - cam1_from_world.row(0);
  A.row(1) = point1.y() * cam1_from_world.row(2) - cam1_from_world.row(1);
  A.row(2) = point2.x() * cam2_from_world.row(2) - cam2_from_world.row(0);
  A.row(3) = point2.y() * cam2_from_world.row(2) - cam2_from_world.row(1);
  return SolveDlt(A.transpose() * A);
}

std::optional<Eigen::Vector3d> TriangulateMultiViewPoint(
    const std::vector<Matrix3x4d>& cams_from_world,
    const std::vector<Eigen::Vector2d>& points) {
  if (cams_from_world.size() != points.size() || points.size() < 2) {
    return std::nullopt;
  }
  Eigen::Matrix4d normal = Eigen::Matrix4d::Zero();
  for (std::size_t i = 0; i < points.size(); ++i) {
    const Matrix3x4d& P = cams_from_world[i];
    const Eigen::RowVector4d row_x = points[i].x() * P.row(2) - P.row(0);
    const Eigen::RowVector4d row_y = points[i].y() * P.row(2) - P.row(1);
    normal += row_x.transpose() * row_x + row_y.transpose() * row_y;
  }
  return SolveDlt(normal);
}

double TriangulationAngleDeg(const Eigen::Vector3d& center1,
                             const Eigen::Vector3d& center2,
                             const Eigen::Vector3d& point) {
  const Eigen::Vector3d ray1 = point - center1;
  const Eigen::Vector3d ray2 = point - center2;
  const double norms = ray1.norm() * ray2.norm();
  if (!(norms > 0)) return 0.0;
  // atan2 of |cross| and dot is accurate for small and large angles alike.
  return std::atan2(ray1.cross(ray2).norm(), ray1.dot(ray2)) * 180.0 / M_PI;
}

bool HasPositiveDepth(const Matrix3x4d& cam_from_world,
                      const Eigen::Vector3d& point) {
  return cam_from_world.row(2).dot(point.homogeneous()) >
         std::numeric_limits<double>::epsilon();
}

std::string TriangulationOptionsProblem(const TriangulationOptions& o) {
  if (!(o.max_error_px > 0) || !std::isfinite(o.max_error_px)) {
    return "TriangulationOptions: max_error_px must be a finite number > 0";
  }
  if (!(o.min_tri_angle_deg >= 0 && o.min_tri_angle_deg < 180)) {
    return "TriangulationOptions: min_tri_angle_deg must be in [0, 180)";
  }
  if (o.min_num_inliers < 2) return "TriangulationOptions: min_num_inliers must be >= 2";
  RansacOptions ransac = o.ransac;
  ransac.max_error = o.max_error_px;
  return RansacOptionsProblem(ransac);
}

bool TriangulationOptions::Check() const {
  return TriangulationOptionsProblem(*this).empty();
}

TriangulationResult EstimateTriangulation(
    const std::vector<TriangulationObservation>& observations,
    const TriangulationOptions& options) {
  ThrowIfInvalid(TriangulationOptionsProblem(options));
  TriangulationResult result;
  if (static_cast<int>(observations.size()) < std::max(2, options.min_num_inliers)) {
    return result;
  }
  const TriangulationEstimator estimator(observations, options);
  RansacOptions ransac = options.ransac;
  ransac.max_error = options.max_error_px;
  ransac.final_refinement = options.refine && ransac.final_refinement;
  const RansacResult<Eigen::Vector3d> report = Ransac(estimator, ransac);
  if (!report.success || report.num_inliers < options.min_num_inliers) {
    return result;
  }
  // The consensus set, after re-estimation, must still be seen under the
  // minimum angle.
  double max_angle = 0;
  std::vector<int> inliers;
  for (int i = 0; i < static_cast<int>(observations.size()); ++i) {
    if (report.inlier_mask[i]) inliers.push_back(i);
  }
  for (std::size_t a = 0; a < inliers.size(); ++a) {
    for (std::size_t b = a + 1; b < inliers.size(); ++b) {
      max_angle = std::max(
          max_angle, TriangulationAngleDeg(estimator.Center(inliers[a]),
                                           estimator.Center(inliers[b]),
                                           report.model));
    }
  }
  if (max_angle < options.min_tri_angle_deg) return result;
  result.success = true;
  result.point = report.model;
  result.inlier_mask = report.inlier_mask;
  result.num_inliers = report.num_inliers;
  return result;
}

}  // namespace flysfm
