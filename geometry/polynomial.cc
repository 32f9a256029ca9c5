#include "geometry/polynomial.h"

#include <cmath>

#include <Eigen/Eigenvalues>

namespace flysfm {
namespace {

// A few Newton steps from `x` on the polynomial; keeps the best iterate.
double PolishRoot(const Eigen::VectorXd& coeffs, double x) {
  double best_x = x;
  double best_value = std::abs(EvaluatePolynomial(coeffs, x));
  for (int iteration = 0; iteration < 8 && best_value > 0; ++iteration) {
    double value = 0;
    double derivative = 0;
    for (int i = 0; i < coeffs.size(); ++i) {
      derivative = derivative * x + value;
      value = value * x + coeffs[i];
    }
    if (derivative == 0 || !std::isfinite(derivative)) break;
    x -= value / derivative;
    const double new_value = std::abs(EvaluatePolynomial(coeffs, x));
    if (!(new_value < best_value)) break;
    best_value = new_value;
    best_x = x;
  }
  return best_x;
}

}  // namespace

double EvaluatePolynomial(const Eigen::VectorXd& coeffs, double x) {
  double value = 0;
  for (int i = 0; i < coeffs.size(); ++i) value = value * x + coeffs[i];
  return value;
}

std::vector<double> RealPolynomialRoots(const Eigen::VectorXd& coeffs,
                                        double imag_tolerance) {
  std::vector<double> roots;
  if (coeffs.size() == 0 || !coeffs.allFinite()) return roots;
  const double scale = coeffs.cwiseAbs().maxCoeff();
  if (scale == 0) return roots;
  int first = 0;
  while (first < coeffs.size() && std::abs(coeffs[first]) <= 1e-14 * scale) {
    ++first;
  }
  const int degree = static_cast<int>(coeffs.size()) - 1 - first;
  if (degree <= 0) return roots;
  const Eigen::VectorXd poly = coeffs.tail(degree + 1) / coeffs[first];
  if (degree == 1) {
    roots.push_back(-poly[1]);
    return roots;
  }
  // Roots at zero (trailing zero coefficients) are split off exactly.
  int num_zero_roots = 0;
  while (num_zero_roots < degree &&
         poly[degree - num_zero_roots] == 0.0) {
    ++num_zero_roots;
  }
  for (int i = 0; i < num_zero_roots; ++i) roots.push_back(0.0);
  const int reduced_degree = degree - num_zero_roots;
  if (reduced_degree == 0) return roots;
  const Eigen::VectorXd reduced = poly.head(reduced_degree + 1);
  if (reduced_degree == 1) {
    roots.push_back(-reduced[1]);
    return roots;
  }
  Eigen::MatrixXd companion = Eigen::MatrixXd::Zero(reduced_degree, reduced_degree);
  companion.row(0) = -reduced.tail(reduced_degree).transpose();
  companion.diagonal(-1).setOnes();
  Eigen::EigenSolver<Eigen::MatrixXd> solver(companion, false);
  if (solver.info() != Eigen::Success) return roots;
  const Eigen::VectorXcd eigenvalues = solver.eigenvalues();
  for (int i = 0; i < eigenvalues.size(); ++i) {
    const std::complex<double> root = eigenvalues[i];
    if (std::abs(root.imag()) > imag_tolerance * (1.0 + std::abs(root.real()))) {
      continue;
    }
    roots.push_back(PolishRoot(reduced, root.real()));
  }
  return roots;
}

std::vector<double> RealCubicRoots(double a, double b, double c, double d) {
  std::vector<double> roots;
  const double scale = std::max({std::abs(a), std::abs(b), std::abs(c), std::abs(d)});
  if (!std::isfinite(scale) || scale == 0) return roots;
  if (std::abs(a) <= 1e-14 * scale) {
    if (std::abs(b) <= 1e-14 * scale) {
      if (std::abs(c) <= 1e-14 * scale) return roots;
      roots.push_back(-d / c);
      return roots;
    }
    const double disc = c * c - 4 * b * d;
    if (disc < 0) return roots;
    // Numerically stable quadratic formula.
    const double q = -0.5 * (c + std::copysign(std::sqrt(disc), c));
    if (q != 0) {
      roots.push_back(q / b);
      roots.push_back(d / q);
    } else {
      roots.push_back(0.0);
    }
    return roots;
  }
  // Depressed cubic t^3 + p t + q with x = t - B/3.
  const double B = b / a;
  const double C = c / a;
  const double D = d / a;
  const double p = C - B * B / 3.0;
  const double q = 2.0 * B * B * B / 27.0 - B * C / 3.0 + D;
  const double shift = -B / 3.0;
  const double disc = q * q / 4.0 + p * p * p / 27.0;
  if (disc > 0) {
    const double s = std::sqrt(disc);
    roots.push_back(std::cbrt(-q / 2.0 + s) + std::cbrt(-q / 2.0 - s) + shift);
  } else if (p == 0) {
    roots.push_back(shift);
  } else {
    // Three real roots (trigonometric form).
    const double r = 2.0 * std::sqrt(-p / 3.0);
    const double arg = std::clamp(3.0 * q / (p * r), -1.0, 1.0);
    const double phi = std::acos(arg) / 3.0;
    for (int k = 0; k < 3; ++k) {
      roots.push_back(r * std::cos(phi - 2.0 * M_PI * k / 3.0) + shift);
    }
  }
  Eigen::VectorXd poly(4);
  poly << 1.0, B, C, D;
  for (double& root : roots) root = PolishRoot(poly, root);
  return roots;
}

}  // namespace flysfm
