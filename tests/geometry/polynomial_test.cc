#include "geometry/polynomial.h"

#include <algorithm>
#include <cmath>
#include <random>

#include <catch2/catch.hpp>

namespace flysfm {
namespace {

// Coefficients (highest first) of prod (x - r_i).
Eigen::VectorXd FromRoots(const std::vector<double>& roots) {
  Eigen::VectorXd coeffs(1);
  coeffs(0) = 1;
  for (const double r : roots) {
    Eigen::VectorXd next = Eigen::VectorXd::Zero(coeffs.size() + 1);
    next.head(coeffs.size()) += coeffs;
    next.tail(coeffs.size()) -= r * coeffs;
    coeffs = next;
  }
  return coeffs;
}

bool ContainsRoot(const std::vector<double>& roots, double root, double tolerance) {
  return std::any_of(roots.begin(), roots.end(), [&](double r) {
    return std::abs(r - root) <= tolerance * (1 + std::abs(root));
  });
}

TEST_CASE("RealPolynomialRoots finds every real root of random polynomials") {
  std::mt19937 rng(1);
  std::uniform_real_distribution<double> uniform(-5, 5);
  for (int instance = 0; instance < 500; ++instance) {
    std::vector<double> roots;
    const int degree = 2 + instance % 9;
    for (int i = 0; i < degree; ++i) roots.push_back(uniform(rng));
    std::sort(roots.begin(), roots.end());
    // Well separated roots only: a cluster is ill-conditioned by nature.
    bool separated = true;
    for (int i = 1; i < degree; ++i) separated &= roots[i] - roots[i - 1] > 0.05;
    if (!separated) continue;
    const std::vector<double> found = RealPolynomialRoots(3.0 * FromRoots(roots));
    REQUIRE(found.size() == roots.size());
    for (const double r : roots) CHECK(ContainsRoot(found, r, 1e-8));
  }
}

TEST_CASE("RealPolynomialRoots skips complex roots and handles leading zeros") {
  // (x^2 + 1)(x - 2) with two leading zero coefficients.
  Eigen::VectorXd coeffs(6);
  coeffs << 0, 0, 1, -2, 1, -2;
  const std::vector<double> roots = RealPolynomialRoots(coeffs);
  REQUIRE(roots.size() == 1);
  CHECK(roots[0] == Approx(2.0).epsilon(1e-12));
  CHECK(RealPolynomialRoots(Eigen::VectorXd::Zero(4)).empty());
  Eigen::VectorXd with_nan(3);
  with_nan << 1, NAN, 1;
  CHECK(RealPolynomialRoots(with_nan).empty());
}

TEST_CASE("RealCubicRoots solves cubics of every kind") {
  std::mt19937 rng(2);
  std::uniform_real_distribution<double> uniform(-3, 3);
  for (int instance = 0; instance < 500; ++instance) {
    const double r1 = uniform(rng), r2 = uniform(rng), r3 = uniform(rng);
    const double a = uniform(rng) + (uniform(rng) > 0 ? 4 : -4);
    const Eigen::VectorXd c = a * FromRoots({r1, r2, r3});
    const std::vector<double> found = RealCubicRoots(c(0), c(1), c(2), c(3));
    for (const double r : {r1, r2, r3}) {
      double closest = 1e9;
      for (const double f : found) closest = std::min(closest, std::abs(f - r));
      // Close double roots are only determined to ~sqrt(eps).
      CHECK(closest < 1e-6);
    }
  }
  // One real root, and lower degrees.
  const std::vector<double> one = RealCubicRoots(1, 0, 1, -2);  // (x-1)(x^2+x+2)
  REQUIRE(one.size() == 1);
  CHECK(one[0] == Approx(1.0).epsilon(1e-12));
  const std::vector<double> quadratic = RealCubicRoots(0, 1, -3, 2);
  CHECK(quadratic.size() == 2);
  CHECK(RealCubicRoots(0, 0, 0, 1).empty());
}

}  // namespace
}  // namespace flysfm
