#include "geometry/statistics.h"

#include <cmath>

#include <catch2/catch.hpp>

namespace flysfm {
namespace {

TEST_CASE("Quantile, Median, Mean and Rms of small samples") {
  CHECK(Median({3, 1, 2}) == 2);
  CHECK(Median({4, 1, 3, 2}) == 2.5);
  CHECK(Quantile({}, 0.5) == 0);
  CHECK(Mean({1, 2, 6}) == 3);
  CHECK(Rms({3, 4}) == Approx(std::sqrt(12.5)));
}

TEST_CASE("Spearman's correlation is 1 for any increasing relation, -1 for a decreasing one") {
  const std::vector<double> x = {0.1, 0.5, 2, 3, 10};
  std::vector<double> cubed, negated;
  for (const double v : x) {
    cubed.push_back(v * v * v);
    negated.push_back(-std::exp(v));
  }
  CHECK(*SpearmanCorrelation(x, cubed) == Approx(1.0));
  CHECK(*SpearmanCorrelation(x, negated) == Approx(-1.0));
}

TEST_CASE("Spearman's correlation matches the textbook formula without ties") {
  // 1 - 6 sum d^2 / (n (n^2 - 1)); ranks of b: 2 1 4 3 5, d^2 sum = 4.
  const std::vector<double> a = {1, 2, 3, 4, 5};
  const std::vector<double> b = {20, 10, 40, 30, 50};
  CHECK(*SpearmanCorrelation(a, b) == Approx(1.0 - 6.0 * 4 / (5 * 24)));
}

TEST_CASE("Spearman's correlation gives tied values their mean rank") {
  // b's ranks: 1.5 1.5 3 4; a's 1 2 3 4. Pearson of the ranks, by hand:
  // deviations a: -1.5 -0.5 0.5 1.5, b: -1 -1 0.5 1.5;
  // sum ab = 1.5 + 0.5 + 0.25 + 2.25 = 4.5, aa = 5, bb = 1 + 1 + 0.25 + 2.25 = 4.5.
  const std::vector<double> a = {1, 2, 3, 4};
  const std::vector<double> b = {7, 7, 8, 9};
  CHECK(*SpearmanCorrelation(a, b) == Approx(4.5 / std::sqrt(5 * 4.5)));
}

TEST_CASE("Spearman's correlation is undefined without an order to compare") {
  CHECK_FALSE(SpearmanCorrelation({1}, {2}));
  CHECK_FALSE(SpearmanCorrelation({1, 2}, {2}));
  CHECK_FALSE(SpearmanCorrelation({1, 2, 3}, {5, 5, 5}));
}

}  // namespace
}  // namespace flysfm
