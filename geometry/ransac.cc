#include "geometry/ransac.h"

#include <stdexcept>
#include <string>

namespace flysfm {

std::string RansacOptionsProblem(const RansacOptions& o) {
  if (!(o.max_error > 0) || !std::isfinite(o.max_error)) {
    return "RansacOptions: max_error must be a finite number > 0, got " +
           std::to_string(o.max_error);
  }
  if (!(o.confidence > 0 && o.confidence < 1)) {
    return "RansacOptions: confidence must be in (0, 1), got " +
           std::to_string(o.confidence);
  }
  if (o.min_iterations < 0) return "RansacOptions: min_iterations must be >= 0";
  if (o.max_iterations < 1) return "RansacOptions: max_iterations must be >= 1";
  if (o.min_iterations > o.max_iterations) {
    return "RansacOptions: min_iterations must not exceed max_iterations";
  }
  if (!(o.min_inlier_ratio >= 0 && o.min_inlier_ratio <= 1)) {
    return "RansacOptions: min_inlier_ratio must be in [0, 1]";
  }
  if (o.lo_max_iterations < 0) return "RansacOptions: lo_max_iterations must be >= 0";
  if (o.max_refinements < 0) return "RansacOptions: max_refinements must be >= 0";
  return "";
}

bool RansacOptions::Check() const { return RansacOptionsProblem(*this).empty(); }

void ThrowIfInvalid(const std::string& problem) {
  if (!problem.empty()) throw std::invalid_argument(problem);
}

int RansacRequiredIterations(int num_inliers, int num_data, int sample_size,
                             double confidence) {
  constexpr int kMax = std::numeric_limits<int>::max();
  if (num_data <= 0 || num_inliers <= 0) return kMax;
  if (num_inliers >= num_data) return 1;
  const double inlier_ratio = static_cast<double>(num_inliers) / num_data;
  const double p_good = std::pow(inlier_ratio, sample_size);
  if (p_good <= 0) return kMax;
  if (p_good >= 1) return 1;
  const double denominator = std::log1p(-p_good);
  if (!(denominator < 0)) return kMax;
  const double iterations = std::ceil(std::log1p(-confidence) / denominator);
  if (!(iterations < kMax)) return kMax;
  return std::max(1, static_cast<int>(iterations));
}

}  // namespace flysfm
