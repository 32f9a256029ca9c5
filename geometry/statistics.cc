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

namespace {

// 1-based ranks, ties given the mean of the ranks they span.
std::vector<double> Ranks(const std::vector<double>& values) {
  std::vector<std::size_t> order(values.size());
  std::iota(order.begin(), order.end(), 0);
  std::sort(order.begin(), order.end(),
            [&](std::size_t i, std::size_t j) { return values[i] < values[j]; });
  std::vector<double> ranks(values.size());
  for (std::size_t begin = 0; begin < order.size();) {
    std::size_t end = begin + 1;
    while (end < order.size() && values[order[end]] == values[order[begin]]) ++end;
    const double rank = 0.5 * double(begin + 1 + end);  // mean of begin+1 .. end
    for (std::size_t k = begin; k < end; ++k) ranks[order[k]] = rank;
    begin = end;
  }
  return ranks;
}

}  // namespace

std::optional<double> SpearmanCorrelation(const std::vector<double>& a,
                                          const std::vector<double>& b) {
  if (a.size() != b.size() || a.size() < 2) return std::nullopt;
  const std::vector<double> ra = Ranks(a), rb = Ranks(b);
  const double mean = 0.5 * double(a.size() + 1);
  double ab = 0, aa = 0, bb = 0;
  for (std::size_t i = 0; i < a.size(); ++i) {
    ab += (ra[i] - mean) * (rb[i] - mean);
    aa += (ra[i] - mean) * (ra[i] - mean);
    bb += (rb[i] - mean) * (rb[i] - mean);
  }
  if (aa == 0 || bb == 0) return std::nullopt;
  return ab / std::sqrt(aa * bb);
}

}  // namespace flysfm
