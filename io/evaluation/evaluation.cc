#include "io/evaluation/evaluation.h"

#include <algorithm>
#include <cmath>
#include <sstream>

#include <nlohmann/json.hpp>

#include "geometry/similarity.h"

namespace flysfm {

std::optional<PositionErrors> ComparePositionsAfterSim3(
    const std::vector<Eigen::Vector3d>& estimated,
    const std::vector<Eigen::Vector3d>& reference) {
  const std::optional<Sim3d> reference_from_estimate =
      SimilarityFromPoints(estimated, reference);
  if (!reference_from_estimate) return std::nullopt;
  std::vector<double> errors;
  for (std::size_t i = 0; i < estimated.size(); ++i) {
    errors.push_back((*reference_from_estimate * estimated[i] - reference[i]).norm());
  }
  PositionErrors result;
  result.reference_from_estimate = *reference_from_estimate;
  result.num_compared = int(errors.size());
  double sum = 0, sum_squares = 0;
  for (const double e : errors) {
    sum += e;
    sum_squares += e * e;
  }
  result.mean = sum / errors.size();
  result.rmse = std::sqrt(sum_squares / errors.size());
  result.max = *std::max_element(errors.begin(), errors.end());
  std::sort(errors.begin(), errors.end());
  const std::size_t n = errors.size();
  result.median = n % 2 ? errors[n / 2] : 0.5 * (errors[n / 2 - 1] + errors[n / 2]);
  return result;
}

std::optional<PositionErrors> CompareCentersByName(
    const Reconstruction& reconstruction,
    const std::map<std::string, Eigen::Vector3d>& reference_centers) {
  std::vector<Eigen::Vector3d> estimated, reference;
  for (const auto& [id, image] : reconstruction.images()) {
    const auto it = reference_centers.find(image.name);
    if (!image.IsRegistered() || it == reference_centers.end()) continue;
    estimated.push_back(ProjectionCenter(*image.cam_from_world));
    reference.push_back(it->second);
  }
  return ComparePositionsAfterSim3(estimated, reference);
}

TrajectoryEvaluation EvaluateTrajectory(const std::vector<StampedPose>& estimated,
                                        const std::vector<StampedPose>& reference,
                                        double max_time_difference) {
  TrajectoryEvaluation evaluation;
  evaluation.num_estimated = int(estimated.size());
  evaluation.num_reference = int(reference.size());
  const auto pairs = AssociateByTimestamp(estimated, reference, max_time_difference);
  evaluation.num_associated = int(pairs.size());
  std::vector<Eigen::Vector3d> estimated_centers, reference_centers;
  for (const auto& [i, j] : pairs) {
    estimated_centers.push_back(estimated[i].world_from_cam.translation);
    reference_centers.push_back(reference[j].world_from_cam.translation);
  }
  evaluation.ate = ComparePositionsAfterSim3(estimated_centers, reference_centers);
  return evaluation;
}

std::string TrajectoryEvaluation::Report() const {
  std::ostringstream out;
  nlohmann::json json = {{"estimated", num_estimated},
                         {"reference", num_reference},
                         {"associated", num_associated}};
  out << "poses: " << num_estimated << " estimated, " << num_reference
      << " in the reference, " << num_associated << " associated\n";
  if (ate) {
    out << "ATE after Sim3 alignment (scale " << ate->reference_from_estimate.scale
        << "): RMSE " << ate->rmse * 100 << " cm, mean " << ate->mean * 100
        << " cm, median " << ate->median * 100 << " cm, max " << ate->max * 100
        << " cm\n";
    json["ate_rmse_m"] = ate->rmse;
    json["ate_mean_m"] = ate->mean;
    json["ate_median_m"] = ate->median;
    json["ate_max_m"] = ate->max;
    json["sim3_scale"] = ate->reference_from_estimate.scale;
  } else {
    out << "ATE: too few associated poses to align (need 3, not collinear)\n";
    json["ate_rmse_m"] = nullptr;
  }
  out << json.dump() << "\n";
  return out.str();
}

}  // namespace flysfm
