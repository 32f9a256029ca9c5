#include "geometry/gric.h"

#include <cmath>
#include <limits>
#include <random>

#include <catch2/catch.hpp>

namespace flysfm {
namespace {

TEST_CASE("Gric adds Torr's penalties to the capped residuals") {
  // n = 3, sigma = 1: F (d = 3, k = 7) caps at 2 (r - d), H (d = 2, k = 8)
  // at 4.
  const std::vector<double> residuals = {0.5, 1.0, 100.0};
  const double lambda1 = std::log(4.0);
  const double lambda2 = std::log(12.0);
  CHECK(Gric(residuals, 1.0, kGricFundamental) ==
        Approx(0.5 + 1.0 + 2.0 + lambda1 * 3 * 3 + lambda2 * 7));
  CHECK(Gric(residuals, 1.0, kGricHomography) ==
        Approx(0.5 + 1.0 + 4.0 + lambda1 * 2 * 3 + lambda2 * 8));
  CHECK(Gric(residuals, 1.0, kGricEssential) ==
        Approx(0.5 + 1.0 + 2.0 + lambda1 * 3 * 3 + lambda2 * 5));
  // Residuals are in units of sigma^2.
  CHECK(Gric({0.5, 1.0}, 2.0, kGricFundamental) ==
        Approx(0.125 + 0.25 + lambda1 * 3 * 2 + std::log(8.0) * 7));
  // Non-finite residuals are capped, a bad sigma gives +inf.
  CHECK(Gric({std::numeric_limits<double>::quiet_NaN()}, 1.0, kGricHomography) ==
        Approx(4.0 + lambda1 * 2 + std::log(4.0) * 8));
  CHECK(std::isinf(Gric(residuals, 0.0, kGricFundamental)));
}

TEST_CASE("EstimateNoiseSigma recovers the sigma of Gaussian residuals") {
  std::mt19937 rng(1);
  for (const double sigma : {0.3, 1.0, 2.5}) {
    std::normal_distribution<double> noise(0, sigma);
    std::vector<double> codim1, codim2;
    for (int i = 0; i < 20000; ++i) {
      const double a = noise(rng), b = noise(rng);
      codim1.push_back(a * a);
      codim2.push_back(a * a + b * b);
    }
    CHECK(EstimateNoiseSigma(codim1, 1) == Approx(sigma).epsilon(0.03));
    CHECK(EstimateNoiseSigma(codim2, 2) == Approx(sigma).epsilon(0.03));
  }
  CHECK(EstimateNoiseSigma({}, 1) == 0.0);
}

}  // namespace
}  // namespace flysfm
