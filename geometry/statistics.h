#pragma once

// Order statistics and means of samples: the one definition the engine,
// the outputs, the benchmarks and the tests share, so that a "median" means
// the same everywhere.

#include <optional>
#include <vector>

namespace flysfm {

// The `fraction` quantile (0: minimum, 1: maximum), interpolated linearly
// between the two nearest order statistics; 0 for no values, so that an
// empty stage prints as 0 ms.
double Quantile(std::vector<double> values, double fraction);
// The mean of the two middle values for an even count.
double Median(std::vector<double> values);
// 0 for no values.
double Mean(const std::vector<double>& values);
// Root mean square; 0 for no values.
double Rms(const std::vector<double>& values);

// Spearman's rank correlation of paired samples: Pearson's correlation of
// their ranks, tied values sharing the mean of their ranks. In [-1, 1]; it
// asks only that one sample grow with the other, not linearly, which is what
// "ranks the points by their error" means. nullopt for different lengths,
// fewer than two pairs, or a sample whose values are all equal (no order to
// compare).
std::optional<double> SpearmanCorrelation(const std::vector<double>& a,
                                          const std::vector<double>& b);

}  // namespace flysfm
