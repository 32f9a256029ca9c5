#include "geometry/gric.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace flysfm {

double Gric(const std::vector<double>& squared_residuals, double sigma,
            GricModel model, int data_dim) {
  if (!(sigma > 0) || !std::isfinite(sigma)) {
    return std::numeric_limits<double>::infinity();
  }
  const double n = static_cast<double>(squared_residuals.size());
  const double r = data_dim;
  const double lambda1 = std::log(r);
  const double lambda2 = std::log(r * std::max(1.0, n));
  const double cap = kGricLambda3 * (r - model.manifold_dim);
  const double inv_sigma2 = 1.0 / (sigma * sigma);
  double sum = 0;
  for (const double e2 : squared_residuals) {
    const double x = e2 * inv_sigma2;
    sum += x < cap ? x : cap;  // NaN and inf count as capped
  }
  return sum + lambda1 * model.manifold_dim * n + lambda2 * model.num_params;
}

double EstimateNoiseSigma(std::vector<double> squared_residuals, int codimension) {
  squared_residuals.erase(
      std::remove_if(squared_residuals.begin(), squared_residuals.end(),
                     [](double e2) { return !std::isfinite(e2); }),
      squared_residuals.end());
  if (squared_residuals.empty()) return 0.0;
  const std::size_t middle = squared_residuals.size() / 2;
  std::nth_element(squared_residuals.begin(), squared_residuals.begin() + middle,
                   squared_residuals.end());
  const double median = squared_residuals[middle];
  // Medians of chi^2 with 1, 2, 3 degrees of freedom.
  static constexpr double kChi2Median[] = {0.454936, 1.386294, 2.365974};
  const int k = std::clamp(codimension, 1, 3);
  return std::sqrt(median / kChi2Median[k - 1]);
}

}  // namespace flysfm
