#include "geometry/statistics.h"

#include <algorithm>
#include <cmath>
#include <numeric>

namespace flysfm {

double Quantile(std::vector<double> values, double fraction) {
  if (values.empty()) return 0;
  const double at = std::clamp(fraction, 0.0, 1.0) * double(values.size() - 1);
  const std::size_t below = std::size_t(std::floor(at));
  const std::size_t above = std::min(below + 1, values.size() - 1);
  // Two partial sorts instead of a whole one: the benchmarks take quantiles
  // of every image's times.
  std::nth_element(values.begin(), values.begin() + below, values.end());
  const double low = values[below];
  if (above == below) return low;
  const double high = *std::min_element(values.begin() + below + 1, values.end());
  return low + (at - double(below)) * (high - low);
}

double Median(std::vector<double> values) { return Quantile(std::move(values), 0.5); }

double Mean(const std::vector<double>& values) {
  if (values.empty()) return 0;
  return std::accumulate(values.begin(), values.end(), 0.0) / double(values.size());
}

double Rms(const std::vector<double>& values) {
  if (values.empty()) return 0;
  double sum = 0;
  for (const double value : values) sum += value * value;
  return std::sqrt(sum / double(values.size()));
}

}  // namespace flysfm
