#pragma once

// Real roots of small univariate polynomials, for the minimal solvers.

#include <vector>

#include <Eigen/Core>

namespace flysfm {

// Real roots of sum_i coeffs[i] x^(n-i) (highest degree first). Leading
// coefficients that are zero relative to the largest one are dropped; roots
// are found as eigenvalues of the companion matrix and polished by Newton's
// method. A root counts as real when its imaginary part is below
// `imag_tolerance` times (1 + |root|). Returns no roots for a constant or
// non-finite polynomial.
std::vector<double> RealPolynomialRoots(const Eigen::VectorXd& coeffs,
                                        double imag_tolerance = 1e-8);

// Real roots of a x^3 + b x^2 + c x + d (any of them may be zero: lower
// degrees are handled), each polished by Newton's method.
std::vector<double> RealCubicRoots(double a, double b, double c, double d);

// Evaluates sum_i coeffs[i] x^(n-i) by Horner's rule.
double EvaluatePolynomial(const Eigen::VectorXd& coeffs, double x);

}  // namespace flysfm
