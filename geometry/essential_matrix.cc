#include "geometry/essential_matrix.h"

#include <array>
#include <cmath>

#include <Eigen/Dense>

#include "geometry/normalization.h"
#include "geometry/triangulation.h"

namespace flysfm {
namespace {

constexpr double kRankTolerance = 1e-10;

// Polynomials of degree <= 3 in (x, y, z): 20 coefficients over the monomials
// in graded reverse lexicographic order,
//   0 x^3, 1 x^2y, 2 x^2z, 3 xy^2, 4 xyz, 5 xz^2, 6 y^3, 7 y^2z, 8 yz^2,
//   9 z^3, 10 x^2, 11 xy, 12 xz, 13 y^2, 14 yz, 15 z^2, 16 x, 17 y, 18 z,
//   19 1.
// Degree-1 polynomials use indices 16..19, degree-2 ones 10..19.
using Poly = std::array<double, 20>;

constexpr int kExponents[20][3] = {
    {3, 0, 0}, {2, 1, 0}, {2, 0, 1}, {1, 2, 0}, {1, 1, 1}, {1, 0, 2}, {0, 3, 0},
    {0, 2, 1}, {0, 1, 2}, {0, 0, 3}, {2, 0, 0}, {1, 1, 0}, {1, 0, 1}, {0, 2, 0},
    {0, 1, 1}, {0, 0, 2}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}, {0, 0, 0}};

struct ProductTable {
  // index[i - 10][j - 16]: monomial of (monomial i) * (monomial j).
  int index[10][4];
  ProductTable() {
    for (int i = 10; i < 20; ++i) {
      for (int j = 16; j < 20; ++j) {
        const int e0 = kExponents[i][0] + kExponents[j][0];
        const int e1 = kExponents[i][1] + kExponents[j][1];
        const int e2 = kExponents[i][2] + kExponents[j][2];
        for (int k = 0; k < 20; ++k) {
          if (kExponents[k][0] == e0 && kExponents[k][1] == e1 &&
              kExponents[k][2] == e2) {
            index[i - 10][j - 16] = k;
          }
        }
      }
    }
  }
};

const ProductTable& Products() {
  static const ProductTable table;
  return table;
}

// p (degree <= 2) times q (degree <= 1).
Poly Multiply(const Poly& p, const Poly& q) {
  const ProductTable& table = Products();
  Poly r{};
  for (int i = 10; i < 20; ++i) {
    if (p[i] == 0) continue;
    for (int j = 16; j < 20; ++j) r[table.index[i - 10][j - 16]] += p[i] * q[j];
  }
  return r;
}

Poly Add(const Poly& a, const Poly& b) {
  Poly r;
  for (int i = 0; i < 20; ++i) r[i] = a[i] + b[i];
  return r;
}

Poly Scale(const Poly& a, double s) {
  Poly r;
  for (int i = 0; i < 20; ++i) r[i] = a[i] * s;
  return r;
}

// Fills the 10x20 matrix of the cubic constraints on E = xX + yY + zZ + W.
void BuildConstraints(const Eigen::Matrix<double, 9, 4>& basis,
                      Eigen::Matrix<double, 10, 20>* M) {
  // E(r, c) as degree-1 polynomials; basis columns are X, Y, Z, W row-major.
  Poly E[3][3];
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) {
      E[r][c] = Poly{};
      for (int k = 0; k < 4; ++k) E[r][c][16 + k] = basis(3 * r + c, k);
    }
  }
  // det(E).
  Poly det = Multiply(Add(Multiply(E[1][1], E[2][2]),
                          Scale(Multiply(E[1][2], E[2][1]), -1)),
                      E[0][0]);
  det = Add(det, Scale(Multiply(Add(Multiply(E[1][0], E[2][2]),
                                    Scale(Multiply(E[1][2], E[2][0]), -1)),
                                E[0][1]),
                       -1));
  det = Add(det, Multiply(Add(Multiply(E[1][0], E[2][1]),
                              Scale(Multiply(E[1][1], E[2][0]), -1)),
                          E[0][2]));
  // E E^T (degree 2), its trace, then 2 E E^T E - tr(E E^T) E (degree 3).
  Poly EEt[3][3];
  for (int r = 0; r < 3; ++r) {
    for (int c = r; c < 3; ++c) {
      Poly sum{};
      for (int k = 0; k < 3; ++k) sum = Add(sum, Multiply(E[r][k], E[c][k]));
      EEt[r][c] = sum;
      EEt[c][r] = sum;
    }
  }
  const Poly trace = Add(Add(EEt[0][0], EEt[1][1]), EEt[2][2]);
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) {
      Poly sum{};
      for (int k = 0; k < 3; ++k) sum = Add(sum, Multiply(EEt[r][k], E[k][c]));
      const Poly equation =
          Add(Scale(sum, 2.0), Scale(Multiply(trace, E[r][c]), -1.0));
      for (int i = 0; i < 20; ++i) (*M)(3 * r + c, i) = equation[i];
    }
  }
  for (int i = 0; i < 20; ++i) (*M)(9, i) = det[i];
}

}  // namespace

std::vector<Eigen::Matrix3d> EssentialFromFivePoints(
    const std::vector<Eigen::Vector2d>& points1,
    const std::vector<Eigen::Vector2d>& points2) {
  std::vector<Eigen::Matrix3d> models;
  if (points1.size() != points2.size() || points1.size() < 5 ||
      !AllFinite(points1) || !AllFinite(points2)) {
    return models;
  }
  const int n = static_cast<int>(points1.size());
  Eigen::Matrix<double, Eigen::Dynamic, 9> A(n, 9);
  for (int i = 0; i < n; ++i) {
    const Eigen::Vector2d& x1 = points1[i];
    const Eigen::Vector2d& x2 = points2[i];
    A.row(i) << x2.x() * x1.x(), x2.x() * x1.y(), x2.x(), x2.y() * x1.x(),
        x2.y() * x1.y(), x2.y(), x1.x(), x1.y(), 1.0;
  }
  // Null space (n = 5: exact; n > 5: the four smallest right singular
  // vectors), through a QR reduction to 9x9.
  Eigen::Matrix<double, 9, 4> basis;
  if (n == 5) {
    // Exact null space: the last four columns of Q in A^T = Q R.
    Eigen::ColPivHouseholderQR<Eigen::Matrix<double, 9, 5>> qr(A.transpose());
    qr.setThreshold(kRankTolerance);
    if (qr.rank() < 5) return models;
    const Eigen::Matrix<double, 9, 9> Q = qr.householderQ();
    basis = Q.rightCols<4>();
  } else {
    Eigen::Matrix<double, 9, 9> R = Eigen::Matrix<double, 9, 9>::Zero();
    if (n > 9) {
      Eigen::HouseholderQR<Eigen::Matrix<double, Eigen::Dynamic, 9>> qr(A);
      R = qr.matrixQR().topRows<9>().triangularView<Eigen::Upper>();
    } else {
      R.topRows(n) = A;
    }
    Eigen::JacobiSVD<Eigen::Matrix<double, 9, 9>> svd(R, Eigen::ComputeFullV);
    const auto& sigma = svd.singularValues();
    if (!(sigma(4) > kRankTolerance * sigma(0))) return models;
    basis = svd.matrixV().rightCols<4>();
  }

  Eigen::Matrix<double, 10, 20> M;
  BuildConstraints(basis, &M);
  // Gauss-Jordan: express the ten cubic monomials in the remaining ten.
  Eigen::FullPivLU<Eigen::Matrix<double, 10, 10>> lu(M.leftCols<10>());
  if (!lu.isInvertible()) return models;
  const Eigen::Matrix<double, 10, 10> B = lu.solve(M.rightCols<10>());
  if (!B.allFinite()) return models;

  // Action matrix of multiplication by x on the basis
  // b = [x^2, xy, xz, y^2, yz, z^2, x, y, z, 1]: x b = action * b.
  Eigen::Matrix<double, 10, 10> action = Eigen::Matrix<double, 10, 10>::Zero();
  for (int i = 0; i < 6; ++i) action.row(i) = -B.row(i);  // x^3 .. xz^2
  action(6, 0) = 1;  // x * x = x^2
  action(7, 1) = 1;  // x * y = xy
  action(8, 2) = 1;  // x * z = xz
  action(9, 6) = 1;  // x * 1 = x
  Eigen::EigenSolver<Eigen::Matrix<double, 10, 10>> eigen(action);
  if (eigen.info() != Eigen::Success) return models;
  const auto& values = eigen.eigenvalues();
  const auto& vectors = eigen.eigenvectors();
  for (int i = 0; i < 10; ++i) {
    if (std::abs(values(i).imag()) > 1e-8 * (1.0 + std::abs(values(i).real()))) {
      continue;
    }
    const Eigen::Matrix<std::complex<double>, 10, 1> v = vectors.col(i);
    if (std::abs(v(9)) < 1e-14 * v.norm()) continue;
    const double x = (v(6) / v(9)).real();
    const double y = (v(7) / v(9)).real();
    const double z = (v(8) / v(9)).real();
    const Eigen::Matrix<double, 9, 1> e =
        x * basis.col(0) + y * basis.col(1) + z * basis.col(2) + basis.col(3);
    Eigen::Matrix3d E;
    E << e(0), e(1), e(2), e(3), e(4), e(5), e(6), e(7), e(8);
    const double norm = E.norm();
    if (!(norm > 0) || !E.allFinite()) continue;
    models.push_back(E / norm);
  }
  return models;
}

Eigen::Matrix3d EssentialFromPose(const Rigid3d& cam2_from_cam1) {
  const Eigen::Vector3d& t = cam2_from_cam1.translation;
  Eigen::Matrix3d skew;
  skew << 0, -t.z(), t.y(), t.z(), 0, -t.x(), -t.y(), t.x(), 0;
  return skew * cam2_from_cam1.rotation.toRotationMatrix();
}

void DecomposeEssentialMatrix(const Eigen::Matrix3d& E, Eigen::Matrix3d* R1,
                              Eigen::Matrix3d* R2, Eigen::Vector3d* t) {
  Eigen::JacobiSVD<Eigen::Matrix3d> svd(E, Eigen::ComputeFullU |
                                               Eigen::ComputeFullV);
  Eigen::Matrix3d U = svd.matrixU();
  Eigen::Matrix3d V = svd.matrixV();
  if (U.determinant() < 0) U = -U;
  if (V.determinant() < 0) V = -V;
  Eigen::Matrix3d W;
  W << 0, 1, 0, -1, 0, 0, 0, 0, 1;
  *R1 = U * W * V.transpose();
  *R2 = U * W.transpose() * V.transpose();
  *t = U.col(2).normalized();
}

int RelativePoseFromEssential(const Eigen::Matrix3d& E,
                              const std::vector<Eigen::Vector2d>& points1,
                              const std::vector<Eigen::Vector2d>& points2,
                              Rigid3d* cam2_from_cam1,
                              std::vector<Eigen::Vector3d>* points3D,
                              std::vector<char>* in_front, double max_depth) {
  if (points1.size() != points2.size() || points1.empty() || !E.allFinite() ||
      !(E.norm() > 0)) {
    return 0;
  }
  Eigen::Matrix3d R1, R2;
  Eigen::Vector3d t;
  DecomposeEssentialMatrix(E, &R1, &R2, &t);
  const Eigen::Matrix3d rotations[4] = {R1, R2, R1, R2};
  const Eigen::Vector3d translations[4] = {t, t, -t, -t};
  const Matrix3x4d cam1 = Matrix3x4d::Identity();
  const int n = static_cast<int>(points1.size());
  // Triangulates match i under hypothesis k; true if in front of both
  // cameras and within max_depth.
  const auto in_front_of = [&](int k, int i, Eigen::Vector3d* point) {
    Matrix3x4d cam2;
    cam2.leftCols<3>() = rotations[k];
    cam2.col(3) = translations[k];
    const auto X = TriangulatePoint(cam1, cam2, points1[i], points2[i]);
    if (!X) return false;
    *point = *X;
    const double depth1 = X->z();
    const double depth2 = (cam2 * X->homogeneous()).z();
    return depth1 > 0 && depth2 > 0 && depth1 < max_depth && depth2 < max_depth;
  };
  // The hypothesis is a majority vote, which an even subset of at most
  // kVoters matches decides as well as all of them; only the winner
  // triangulates every match (two-view verification calls this per pair).
  constexpr int kVoters = 100;
  const int stride = std::max(1, n / kVoters);
  int best = -1;
  int best_votes = 0;
  Eigen::Vector3d point;
  for (int k = 0; k < 4; ++k) {
    int votes = 0;
    for (int i = 0; i < n; i += stride) votes += in_front_of(k, i, &point);
    if (votes > best_votes) {
      best_votes = votes;
      best = k;
    }
  }
  if (best < 0) return 0;
  std::vector<Eigen::Vector3d> best_points(n, Eigen::Vector3d::Zero());
  std::vector<char> best_flags(n, 0);
  int best_count = 0;
  for (int i = 0; i < n; ++i) {
    point.setZero();
    if (in_front_of(best, i, &point)) {
      best_flags[i] = 1;
      ++best_count;
    }
    best_points[i] = point;
  }
  *cam2_from_cam1 = Rigid3d(rotations[best], translations[best]);
  if (points3D) *points3D = std::move(best_points);
  if (in_front) *in_front = std::move(best_flags);
  return best_count;
}

}  // namespace flysfm

namespace flysfm {
namespace {

// Signed square root of the Sampson error: residual of one match.
double SampsonResidual(const Eigen::Matrix3d& E, const Eigen::Vector2d& x1,
                       const Eigen::Vector2d& x2) {
  const Eigen::Vector3d Ex1 = E * x1.homogeneous();
  const Eigen::Vector3d Etx2 = E.transpose() * x2.homogeneous();
  const double c = x2.homogeneous().dot(Ex1);
  const double denominator = Ex1.head<2>().squaredNorm() + Etx2.head<2>().squaredNorm();
  if (!(denominator > 0)) return std::numeric_limits<double>::infinity();
  return c / std::sqrt(denominator);
}

Eigen::Matrix3d ExpRotation(const Eigen::Vector3d& omega) {
  const double angle = omega.norm();
  if (angle == 0) return Eigen::Matrix3d::Identity();
  return Eigen::AngleAxisd(angle, omega / angle).toRotationMatrix();
}

// Two unit vectors orthogonal to t (and to each other).
void TangentBasis(const Eigen::Vector3d& t, Eigen::Vector3d* b1, Eigen::Vector3d* b2) {
  const Eigen::Vector3d helper =
      std::abs(t.x()) < 0.9 ? Eigen::Vector3d::UnitX() : Eigen::Vector3d::UnitY();
  *b1 = t.cross(helper).normalized();
  *b2 = t.cross(*b1).normalized();
}

}  // namespace

bool RefineRelativePose(const std::vector<Eigen::Vector2d>& points1,
                        const std::vector<Eigen::Vector2d>& points2,
                        const std::vector<int>& indices, Rigid3d* cam2_from_cam1,
                        int max_iterations) {
  if (points1.size() != points2.size()) return false;
  std::vector<int> all;
  const std::vector<int>* used = &indices;
  if (indices.empty()) {
    all.resize(points1.size());
    for (std::size_t i = 0; i < all.size(); ++i) all[i] = static_cast<int>(i);
    used = &all;
  }
  const int n = static_cast<int>(used->size());
  if (n < 5) return false;
  Eigen::Matrix3d R = cam2_from_cam1->rotation.toRotationMatrix();
  Eigen::Vector3d t = cam2_from_cam1->translation;
  if (!(t.norm() > 0) || !R.allFinite() || !t.allFinite()) return false;
  t.normalize();

  auto update = [](const Eigen::Matrix3d& rotation, const Eigen::Vector3d& translation,
                   const Eigen::Matrix<double, 5, 1>& delta, Eigen::Matrix3d* R_new,
                   Eigen::Vector3d* t_new) {
    Eigen::Vector3d b1, b2;
    TangentBasis(translation, &b1, &b2);
    *R_new = ExpRotation(delta.head<3>()) * rotation;
    *t_new = (translation + delta(3) * b1 + delta(4) * b2).normalized();
  };
  auto residuals = [&](const Eigen::Matrix3d& rotation, const Eigen::Vector3d& translation,
                       Eigen::VectorXd* r) {
    Eigen::Matrix3d skew;
    skew << 0, -translation.z(), translation.y(), translation.z(), 0,
        -translation.x(), -translation.y(), translation.x(), 0;
    const Eigen::Matrix3d E = skew * rotation;
    r->resize(n);
    for (int k = 0; k < n; ++k) {
      (*r)(k) = SampsonResidual(E, points1[(*used)[k]], points2[(*used)[k]]);
    }
    return r->allFinite() ? r->squaredNorm() : std::numeric_limits<double>::infinity();
  };

  Eigen::VectorXd r, r_step;
  double cost = residuals(R, t, &r);
  if (!std::isfinite(cost)) return false;
  const double initial_cost = cost;
  double lambda = 1e-4;
  Eigen::MatrixXd J(n, 5);
  for (int iteration = 0; iteration < max_iterations; ++iteration) {
    // Forward differences: the Jacobian only steers the steps, the
    // residuals decide acceptance, so its accuracy does not limit the
    // optimum reached.
    constexpr double kStep = 1e-8;
    for (int k = 0; k < 5; ++k) {
      Eigen::Matrix<double, 5, 1> delta = Eigen::Matrix<double, 5, 1>::Zero();
      Eigen::Matrix3d R_plus;
      Eigen::Vector3d t_plus;
      delta(k) = kStep;
      update(R, t, delta, &R_plus, &t_plus);
      Eigen::VectorXd r_plus;
      residuals(R_plus, t_plus, &r_plus);
      J.col(k) = (r_plus - r) / kStep;
    }
    const Eigen::Matrix<double, 5, 5> JtJ = J.transpose() * J;
    const Eigen::Matrix<double, 5, 1> Jtr = J.transpose() * r;
    bool accepted = false;
    bool converged = false;
    for (int attempt = 0; attempt < 10 && !accepted; ++attempt) {
      Eigen::Matrix<double, 5, 5> A = JtJ;
      A.diagonal() += lambda * JtJ.diagonal().cwiseMax(1e-12);
      const Eigen::Matrix<double, 5, 1> delta = A.ldlt().solve(-Jtr);
      if (!delta.allFinite()) return false;
      Eigen::Matrix3d R_new;
      Eigen::Vector3d t_new;
      update(R, t, delta, &R_new, &t_new);
      const double new_cost = residuals(R_new, t_new, &r_step);
      if (new_cost < cost) {
        converged = cost - new_cost < 1e-14 * (1.0 + cost);
        R = R_new;
        t = t_new;
        r = r_step;
        cost = new_cost;
        lambda = std::max(lambda * 0.1, 1e-12);
        accepted = true;
      } else {
        lambda *= 10;
      }
    }
    if (!accepted || converged) break;
  }
  if (!(cost < initial_cost)) return false;
  *cam2_from_cam1 = Rigid3d(Eigen::Quaterniond(R).normalized(), t);
  return true;
}

}  // namespace flysfm
