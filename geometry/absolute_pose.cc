#include "geometry/absolute_pose.h"

#include <cmath>
#include <stdexcept>
#include <string>

#include <Eigen/Dense>

#include "geometry/estimators.h"
#include "geometry/normalization.h"
#include "geometry/polynomial.h"
#include "geometry/similarity.h"

namespace flysfm {
namespace {

// Polynomials in v as coefficient arrays, lowest degree first.
template <int N>
using PolyV = Eigen::Matrix<double, N, 1>;

template <int A, int B>
PolyV<A + B - 1> MultiplyPoly(const PolyV<A>& a, const PolyV<B>& b) {
  PolyV<A + B - 1> r = PolyV<A + B - 1>::Zero();
  for (int i = 0; i < A; ++i) {
    for (int j = 0; j < B; ++j) r(i + j) += a(i) * b(j);
  }
  return r;
}

double Reprojection2(const Rigid3d& pose, const std::vector<Eigen::Vector2d>& x,
                     const std::vector<Eigen::Vector3d>& X) {
  double sum = 0;
  for (std::size_t i = 0; i < x.size(); ++i) {
    const Eigen::Vector3d p = pose * X[i];
    if (!(p.z() > 0)) return std::numeric_limits<double>::infinity();
    sum += (p.hnormalized() - x[i]).squaredNorm();
  }
  return sum;
}

// ---------------------------------------------------------------- EPnP --

// Control point k (0..3) of the 12-vector v.
Eigen::Vector3d ControlPoint(const Eigen::Matrix<double, 12, 1>& v, int k) {
  return v.segment<3>(3 * k);
}

constexpr int kPairs[6][2] = {{0, 1}, {0, 2}, {0, 3}, {1, 2}, {1, 3}, {2, 3}};

struct EPnPProblem {
  std::vector<Eigen::Vector3d> world_controls;  // 4
  std::vector<Eigen::Vector4d> alphas;          // per point
  Eigen::Matrix<double, 12, 4> kernel;          // smallest 4 eigenvectors
  Eigen::Matrix<double, 6, 10> L;
  Eigen::Matrix<double, 6, 1> rho;
};

// Gauss-Newton on the betas: || L b(beta) - rho ||^2.
void RefineBetas(const Eigen::Matrix<double, 6, 10>& L,
                 const Eigen::Matrix<double, 6, 1>& rho, Eigen::Vector4d* beta) {
  Eigen::Vector4d b = *beta;
  for (int iteration = 0; iteration < 5; ++iteration) {
    Eigen::Matrix<double, 6, 4> A;
    Eigen::Matrix<double, 6, 1> r;
    for (int j = 0; j < 6; ++j) {
      const auto l = L.row(j);
      A(j, 0) = 2 * l(0) * b(0) + l(1) * b(1) + l(3) * b(2) + l(6) * b(3);
      A(j, 1) = l(1) * b(0) + 2 * l(2) * b(1) + l(4) * b(2) + l(7) * b(3);
      A(j, 2) = l(3) * b(0) + l(4) * b(1) + 2 * l(5) * b(2) + l(8) * b(3);
      A(j, 3) = l(6) * b(0) + l(7) * b(1) + l(8) * b(2) + 2 * l(9) * b(3);
      const double value =
          l(0) * b(0) * b(0) + l(1) * b(0) * b(1) + l(2) * b(1) * b(1) +
          l(3) * b(0) * b(2) + l(4) * b(1) * b(2) + l(5) * b(2) * b(2) +
          l(6) * b(0) * b(3) + l(7) * b(1) * b(3) + l(8) * b(2) * b(3) +
          l(9) * b(3) * b(3);
      r(j) = rho(j) - value;
    }
    const Eigen::Vector4d delta = A.colPivHouseholderQr().solve(r);
    if (!delta.allFinite()) break;
    b += delta;
  }
  if (b.allFinite()) *beta = b;
}

std::optional<Rigid3d> PoseFromBetas(const EPnPProblem& problem,
                                     const Eigen::Vector4d& beta,
                                     const std::vector<Eigen::Vector3d>& points3D) {
  const Eigen::Matrix<double, 12, 1> controls = problem.kernel * beta;
  std::vector<Eigen::Vector3d> in_cam(points3D.size());
  for (std::size_t i = 0; i < points3D.size(); ++i) {
    in_cam[i].setZero();
    for (int k = 0; k < 4; ++k) in_cam[i] += problem.alphas[i](k) * ControlPoint(controls, k);
  }
  // The kernel's sign is arbitrary: put the points in front of the camera.
  int positive = 0;
  for (const auto& p : in_cam) positive += p.z() > 0;
  if (2 * positive < static_cast<int>(in_cam.size())) {
    for (auto& p : in_cam) p = -p;
  }
  return RigidFromPoints(points3D, in_cam);
}

}  // namespace

// ----------------------------------------------------------------- P3P --

std::vector<Rigid3d> P3P(const std::vector<Eigen::Vector2d>& points2D,
                         const std::vector<Eigen::Vector3d>& points3D) {
  std::vector<Rigid3d> poses;
  if (points2D.size() != 3 || points3D.size() != 3 || !AllFinite(points2D) ||
      !AllFinite(points3D)) {
    return poses;
  }
  const Eigen::Vector3d f1 = points2D[0].homogeneous().normalized();
  const Eigen::Vector3d f2 = points2D[1].homogeneous().normalized();
  const Eigen::Vector3d f3 = points2D[2].homogeneous().normalized();
  const Eigen::Vector3d& X1 = points3D[0];
  const Eigen::Vector3d& X2 = points3D[1];
  const Eigen::Vector3d& X3 = points3D[2];
  const double a2 = (X2 - X3).squaredNorm();
  const double b2 = (X1 - X3).squaredNorm();
  const double c2 = (X1 - X2).squaredNorm();
  const double scale2 = std::max({a2, b2, c2});
  // Collinear or coincident world points.
  if (!(scale2 > 0) || !((X2 - X1).cross(X3 - X1).squaredNorm() > 1e-20 * scale2 * scale2)) {
    return poses;
  }
  // Repeated rays.
  if (f1.cross(f2).squaredNorm() < 1e-24 || f1.cross(f3).squaredNorm() < 1e-24 ||
      f2.cross(f3).squaredNorm() < 1e-24) {
    return poses;
  }
  const double cos_alpha = f2.dot(f3);
  const double cos_beta = f1.dot(f3);
  const double cos_gamma = f1.dot(f2);
  // Depths s_i along the rays, s2 = u s1, s3 = v s1; with lengths divided by
  // b^2:
  //   (I)  1 + u^2 - 2 u cos_gamma = c (1 + v^2 - 2 v cos_beta)
  //   (II) u^2 + v^2 - 2 u v cos_alpha = a (1 + v^2 - 2 v cos_beta).
  // (I) - (II) is linear in u: u = D(v) / G(v); substituting into (I) gives
  // the quartic b D^2 + p1 D G + P0 G^2 = 0.
  const double a = a2 / b2;
  const double c = c2 / b2;
  PolyV<3> D, P0;
  PolyV<2> G;
  D << c - a - 1, 2 * cos_beta * (a - c), 1 - a + c;
  G << -2 * cos_gamma, 2 * cos_alpha;
  P0 << 1 - c, 2 * c * cos_beta, -c;
  const double p1 = -2 * cos_gamma;
  PolyV<5> quartic = MultiplyPoly<3, 3>(D, D) +
                     MultiplyPoly<3, 3>(P0, MultiplyPoly<2, 2>(G, G));
  quartic.head<4>() += p1 * MultiplyPoly<3, 2>(D, G);
  Eigen::VectorXd high_first(5);
  for (int i = 0; i < 5; ++i) high_first(i) = quartic(4 - i);
  const std::vector<Eigen::Vector3d> rays = {f1, f2, f3};
  for (const double v : RealPolynomialRoots(high_first)) {
    if (!(v > 0)) continue;
    const double g = G(0) + G(1) * v;
    if (std::abs(g) < 1e-14) continue;
    const double u = (D(0) + D(1) * v + D(2) * v * v) / g;
    if (!(u > 0)) continue;
    const double denominator = 1 + v * v - 2 * v * cos_beta;
    if (!(denominator > 0)) continue;
    const double s1 = std::sqrt(b2 / denominator);
    const double depths[3] = {s1, u * s1, v * s1};
    std::vector<Eigen::Vector3d> in_cam(3);
    for (int i = 0; i < 3; ++i) in_cam[i] = depths[i] * rays[i];
    const auto pose = RigidFromPoints(points3D, in_cam);
    if (!pose) continue;
    bool in_front = true;
    for (int i = 0; i < 3; ++i) in_front &= ((*pose) * points3D[i]).z() > 0;
    if (in_front) poses.push_back(*pose);
  }
  return poses;
}

namespace {

// beta0, beta1 (up to a common sign) from the products b00 = beta0^2,
// b01 = beta0 beta1, b11 = beta1^2 of EPnP's approximations; b00 and b11
// share a sign when the solution is real.
void BetasFromProducts(double b00, double b01, double b11, Eigen::Vector4d* beta) {
  if (b00 < 0) {
    (*beta)(0) = std::sqrt(-b00);
    (*beta)(1) = b11 < 0 ? std::sqrt(-b11) : 0.0;
  } else {
    (*beta)(0) = std::sqrt(b00);
    (*beta)(1) = b11 > 0 ? std::sqrt(b11) : 0.0;
  }
  if (b01 < 0) (*beta)(0) = -(*beta)(0);
}

}  // namespace

// ---------------------------------------------------------------- EPnP --

std::vector<Rigid3d> EPnP(const std::vector<Eigen::Vector2d>& points2D,
                          const std::vector<Eigen::Vector3d>& points3D) {
  std::vector<Rigid3d> poses;
  if (points2D.size() != points3D.size() || points2D.size() < 4 ||
      !AllFinite(points2D) || !AllFinite(points3D)) {
    return poses;
  }
  const int n = static_cast<int>(points3D.size());
  EPnPProblem problem;
  // Control points: centroid and the principal axes scaled by their spread.
  Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
  for (const auto& X : points3D) centroid += X;
  centroid /= n;
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Zero();
  for (const auto& X : points3D) {
    covariance += (X - centroid) * (X - centroid).transpose();
  }
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> pca(covariance);
  const Eigen::Vector3d spread = pca.eigenvalues();  // ascending
  if (!(spread(0) > 1e-10 * spread(2))) return poses;  // planar or collinear
  problem.world_controls.push_back(centroid);
  for (int k = 0; k < 3; ++k) {
    problem.world_controls.push_back(
        centroid + std::sqrt(spread(2 - k) / n) * pca.eigenvectors().col(2 - k));
  }
  Eigen::Matrix3d C;
  for (int k = 0; k < 3; ++k) C.col(k) = problem.world_controls[k + 1] - centroid;
  const Eigen::Matrix3d C_inv = C.inverse();
  problem.alphas.resize(n);
  Eigen::Matrix<double, 12, 12> MtM = Eigen::Matrix<double, 12, 12>::Zero();
  for (int i = 0; i < n; ++i) {
    const Eigen::Vector3d a = C_inv * (points3D[i] - centroid);
    problem.alphas[i] << 1 - a.sum(), a(0), a(1), a(2);
    Eigen::Matrix<double, 2, 12> rows = Eigen::Matrix<double, 2, 12>::Zero();
    for (int k = 0; k < 4; ++k) {
      const double alpha = problem.alphas[i](k);
      rows(0, 3 * k) = alpha;
      rows(0, 3 * k + 2) = -alpha * points2D[i].x();
      rows(1, 3 * k + 1) = alpha;
      rows(1, 3 * k + 2) = -alpha * points2D[i].y();
    }
    MtM += rows.transpose() * rows;
  }
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix<double, 12, 12>> eigen(MtM);
  if (eigen.info() != Eigen::Success) return poses;
  problem.kernel = eigen.eigenvectors().leftCols<4>();  // ascending eigenvalues

  // L: squared distances between control points as linear functions of the
  // products beta_a beta_b, ordered b00 b01 b11 b02 b12 b22 b03 b13 b23 b33.
  for (int j = 0; j < 6; ++j) {
    Eigen::Vector3d dv[4];
    for (int k = 0; k < 4; ++k) {
      const Eigen::Matrix<double, 12, 1> v = problem.kernel.col(k);
      dv[k] = ControlPoint(v, kPairs[j][0]) - ControlPoint(v, kPairs[j][1]);
    }
    problem.L.row(j) << dv[0].dot(dv[0]), 2 * dv[0].dot(dv[1]), dv[1].dot(dv[1]),
        2 * dv[0].dot(dv[2]), 2 * dv[1].dot(dv[2]), dv[2].dot(dv[2]),
        2 * dv[0].dot(dv[3]), 2 * dv[1].dot(dv[3]), 2 * dv[2].dot(dv[3]),
        dv[3].dot(dv[3]);
    problem.rho(j) = (problem.world_controls[kPairs[j][0]] -
                      problem.world_controls[kPairs[j][1]]).squaredNorm();
  }

  std::vector<Eigen::Vector4d> initial_betas;
  {  // N = 4 approximation: b00 b01 b02 b03.
    Eigen::Matrix<double, 6, 4> L4;
    L4 << problem.L.col(0), problem.L.col(1), problem.L.col(3), problem.L.col(6);
    const Eigen::Vector4d B = L4.jacobiSvd(Eigen::ComputeFullU | Eigen::ComputeFullV)
                                  .solve(problem.rho);
    Eigen::Vector4d beta;
    if (B(0) < 0) {
      beta(0) = std::sqrt(-B(0));
      beta.tail<3>() = -B.tail<3>() / beta(0);
    } else {
      beta(0) = std::sqrt(B(0));
      beta.tail<3>() = B.tail<3>() / beta(0);
    }
    initial_betas.push_back(beta);
  }
  {  // N = 2 approximation: b00 b01 b11.
    const Eigen::Matrix<double, 6, 3> L3 = problem.L.leftCols<3>();
    const Eigen::Vector3d B = L3.jacobiSvd(Eigen::ComputeFullU | Eigen::ComputeFullV)
                                  .solve(problem.rho);
    Eigen::Vector4d beta = Eigen::Vector4d::Zero();
    BetasFromProducts(B(0), B(1), B(2), &beta);
    initial_betas.push_back(beta);
  }
  {  // N = 3 approximation: b00 b01 b11 b02 b12.
    const Eigen::Matrix<double, 6, 5> L5 = problem.L.leftCols<5>();
    const Eigen::Matrix<double, 5, 1> B =
        L5.jacobiSvd(Eigen::ComputeFullU | Eigen::ComputeFullV).solve(problem.rho);
    Eigen::Vector4d beta = Eigen::Vector4d::Zero();
    BetasFromProducts(B(0), B(1), B(2), &beta);
    beta(2) = beta(0) != 0 ? B(3) / beta(0) : 0.0;
    initial_betas.push_back(beta);
  }

  double best_error = std::numeric_limits<double>::infinity();
  std::optional<Rigid3d> best;
  for (Eigen::Vector4d beta : initial_betas) {
    if (!beta.allFinite()) continue;
    RefineBetas(problem.L, problem.rho, &beta);
    const auto pose = PoseFromBetas(problem, beta, points3D);
    if (!pose) continue;
    const double error = Reprojection2(*pose, points2D, points3D);
    if (error < best_error) {
      best_error = error;
      best = pose;
    }
  }
  if (!best) return poses;
  // The betas' Gauss-Newton minimizes an algebraic error; a few steps on the
  // reprojection error make the pose exact on exact data.
  RefineAbsolutePose(points2D, points3D, {}, &*best, 10);
  poses.push_back(*best);
  return poses;
}

// ------------------------------------------------------------- Refine --

bool RefineAbsolutePose(const std::vector<Eigen::Vector2d>& points2D,
                        const std::vector<Eigen::Vector3d>& points3D,
                        const std::vector<int>& indices, Rigid3d* cam_from_world,
                        int max_iterations) {
  if (points2D.size() != points3D.size()) return false;
  std::vector<int> all;
  const std::vector<int>* used = &indices;
  if (indices.empty()) {
    all.resize(points2D.size());
    for (std::size_t i = 0; i < all.size(); ++i) all[i] = static_cast<int>(i);
    used = &all;
  }
  if (used->size() < 3) return false;
  Eigen::Matrix3d R = cam_from_world->rotation.toRotationMatrix();
  Eigen::Vector3d t = cam_from_world->translation;
  auto cost_of = [&](const Eigen::Matrix3d& rotation, const Eigen::Vector3d& translation) {
    double cost = 0;
    for (const int i : *used) {
      const Eigen::Vector3d p = rotation * points3D[i] + translation;
      if (!(p.z() > std::numeric_limits<double>::epsilon())) {
        return std::numeric_limits<double>::infinity();
      }
      cost += (p.hnormalized() - points2D[i]).squaredNorm();
    }
    return cost;
  };
  double cost = cost_of(R, t);
  if (!std::isfinite(cost)) return false;
  const double initial_cost = cost;
  double lambda = 1e-4;
  for (int iteration = 0; iteration < max_iterations; ++iteration) {
    Eigen::Matrix<double, 6, 6> JtJ = Eigen::Matrix<double, 6, 6>::Zero();
    Eigen::Matrix<double, 6, 1> Jtr = Eigen::Matrix<double, 6, 1>::Zero();
    for (const int i : *used) {
      const Eigen::Vector3d RX = R * points3D[i];
      const Eigen::Vector3d p = RX + t;
      const double inv_z = 1.0 / p.z();
      const Eigen::Vector2d r(p.x() * inv_z - points2D[i].x(),
                              p.y() * inv_z - points2D[i].y());
      Eigen::Matrix<double, 2, 3> dproj;
      dproj << inv_z, 0, -p.x() * inv_z * inv_z, 0, inv_z, -p.y() * inv_z * inv_z;
      Eigen::Matrix3d skew;
      skew << 0, -RX.z(), RX.y(), RX.z(), 0, -RX.x(), -RX.y(), RX.x(), 0;
      Eigen::Matrix<double, 2, 6> J;
      J.leftCols<3>() = -dproj * skew;  // left rotation increment
      J.rightCols<3>() = dproj;
      JtJ += J.transpose() * J;
      Jtr += J.transpose() * r;
    }
    bool accepted = false;
    for (int attempt = 0; attempt < 10 && !accepted; ++attempt) {
      Eigen::Matrix<double, 6, 6> A = JtJ;
      A.diagonal() += lambda * JtJ.diagonal().cwiseMax(1e-12);
      const Eigen::Matrix<double, 6, 1> delta = A.ldlt().solve(-Jtr);
      if (!delta.allFinite()) return false;
      const Eigen::Vector3d omega = delta.head<3>();
      const double angle = omega.norm();
      const Eigen::Matrix3d dR =
          angle > 0 ? Eigen::AngleAxisd(angle, omega / angle).toRotationMatrix()
                    : Eigen::Matrix3d::Identity();
      const Eigen::Matrix3d R_new = dR * R;
      const Eigen::Vector3d t_new = t + delta.tail<3>();
      const double new_cost = cost_of(R_new, t_new);
      if (new_cost < cost) {
        const bool converged = cost - new_cost < 1e-14 * (1.0 + cost);
        R = R_new;
        t = t_new;
        cost = new_cost;
        lambda = std::max(lambda * 0.1, 1e-12);
        accepted = true;
        if (converged) iteration = max_iterations;
      } else {
        lambda *= 10;
      }
    }
    if (!accepted) break;
  }
  if (!(cost < initial_cost)) return false;
  *cam_from_world = Rigid3d(Eigen::Quaterniond(R).normalized(), t);
  return true;
}

// ------------------------------------------------------------- RANSAC --

std::string AbsolutePoseOptionsProblem(const AbsolutePoseOptions& o) {
  if (!(o.max_error_px > 0) || !std::isfinite(o.max_error_px)) {
    return "AbsolutePoseOptions: max_error_px must be a finite number > 0";
  }
  if (o.min_num_inliers < 3) return "AbsolutePoseOptions: min_num_inliers must be >= 3";
  RansacOptions ransac = o.ransac;
  ransac.max_error = 1.0;
  return RansacOptionsProblem(ransac);
}

bool AbsolutePoseOptions::Check() const {
  return AbsolutePoseOptionsProblem(*this).empty();
}

namespace {

// Normalized image coordinates; a non-finite pixel stays non-finite, so that
// it is never an inlier.
std::vector<Eigen::Vector2d> NormalizedPixels(const Camera& camera,
                                              const std::vector<Eigen::Vector2d>& pixels) {
  std::vector<Eigen::Vector2d> normalized(pixels.size());
  for (std::size_t i = 0; i < pixels.size(); ++i) {
    normalized[i] = pixels[i].allFinite()
                        ? camera.CamFromImg(pixels[i])
                        : Eigen::Vector2d::Constant(std::numeric_limits<double>::quiet_NaN());
  }
  return normalized;
}

}  // namespace

AbsolutePoseResult EstimateAbsolutePose(const Camera& camera,
                                        const std::vector<Eigen::Vector2d>& pixels,
                                        const std::vector<Eigen::Vector3d>& points3D,
                                        const AbsolutePoseOptions& options) {
  ThrowIfInvalid(AbsolutePoseOptionsProblem(options));
  AbsolutePoseResult result;
  if (pixels.size() != points3D.size() || !camera.IsValid() ||
      static_cast<int>(pixels.size()) < std::max(3, options.min_num_inliers)) {
    return result;
  }
  const std::vector<Eigen::Vector2d> normalized = NormalizedPixels(camera, pixels);
  const AbsolutePoseEstimator estimator(normalized, points3D);
  RansacOptions ransac = options.ransac;
  ransac.max_error = camera.CamFromImgThreshold(options.max_error_px);
  ransac.final_refinement = options.refine && ransac.final_refinement;
  const RansacResult<Matrix3x4d> report = Ransac(estimator, ransac);
  result.num_iterations = report.num_iterations;
  if (!report.success || report.num_inliers < options.min_num_inliers) {
    return result;
  }
  result.success = true;
  result.cam_from_world = AbsolutePoseEstimator::ToRigid(report.model);
  result.inlier_mask = report.inlier_mask;
  result.num_inliers = report.num_inliers;
  return result;
}

AbsolutePoseResult ReestimateAbsolutePose(const Camera& camera,
                                          const std::vector<Eigen::Vector2d>& pixels,
                                          const std::vector<Eigen::Vector3d>& points3D,
                                          const Rigid3d& first,
                                          const AbsolutePoseOptions& options) {
  AbsolutePoseResult result = EstimateAbsolutePose(camera, pixels, points3D, options);
  if (result.success || pixels.size() != points3D.size()) return result;
  const std::vector<Eigen::Vector2d> normalized = NormalizedPixels(camera, pixels);
  const AbsolutePoseEstimator estimator(normalized, points3D);
  const Matrix3x4d model = first.ToMatrix();
  const double max_error = camera.CamFromImgThreshold(options.max_error_px);
  result.success = true;
  result.cam_from_world = first;
  result.inlier_mask.assign(pixels.size(), 0);
  for (int i = 0; i < estimator.NumData(); ++i) {
    result.inlier_mask[i] = estimator.SquaredError(model, i) <= max_error * max_error;
    result.num_inliers += result.inlier_mask[i];
  }
  return result;
}

}  // namespace flysfm
