#include "io/evaluation/evaluation.h"

#include <algorithm>
#include <cmath>
#include <sstream>

#include <nlohmann/json.hpp>

#include "geometry/similarity.h"
#include "geometry/triangulation.h"

namespace flysfm {
namespace {

double Median(std::vector<double> values) {
  std::sort(values.begin(), values.end());
  const std::size_t n = values.size();
  return n % 2 ? values[n / 2] : 0.5 * (values[n / 2 - 1] + values[n / 2]);
}

double Rms(const std::vector<double>& values) {
  double sum = 0;
  for (const double v : values) sum += v * v;
  return std::sqrt(sum / values.size());
}

}  // namespace

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
  result.median = Median(std::move(errors));
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

std::optional<PoseFit> FitObservationsToPoses(
    const Reconstruction& reconstruction,
    const std::map<std::string, Rigid3d>& true_cam_from_world) {
  // Every observation an inlier, however far off: the DLT of them all, then
  // Gauss-Newton on their pixel errors, whatever the angle between the rays.
  TriangulationOptions triangulation;
  triangulation.max_error_px = 1e9;
  triangulation.min_tri_angle_deg = 0;
  std::vector<double> model_errors, truth_errors;
  for (const auto& [point3D_id, point3D] : reconstruction.points3D()) {
    std::vector<TriangulationObservation> views;
    std::vector<double> own;
    for (const TrackElement& element : point3D.track) {
      const Image& image = reconstruction.image(element.image_id);
      const auto truth = true_cam_from_world.find(image.name);
      if (truth == true_cam_from_world.end()) continue;
      views.push_back({truth->second, &reconstruction.camera(image.camera_id),
                       image.points2D[element.point2D_idx].xy});
      own.push_back(
          reconstruction.ReprojectionError(element.image_id, element.point2D_idx, point3D.xyz));
    }
    if (views.size() < 2) continue;
    const TriangulationResult point = EstimateTriangulation(views, triangulation);
    // A point behind one of the true cameras is no inlier there.
    if (!point.success || point.num_inliers != int(views.size())) continue;
    for (std::size_t i = 0; i < views.size(); ++i) {
      const TriangulationObservation& view = views[i];
      model_errors.push_back(own[i]);
      truth_errors.push_back(
          (view.camera->ImgFromCam(view.cam_from_world * point.point) - view.pixel).norm());
    }
  }
  if (model_errors.empty()) return std::nullopt;
  PoseFit fit;
  fit.num_observations = int(model_errors.size());
  fit.model_median_px = Median(model_errors);
  fit.truth_median_px = Median(truth_errors);
  fit.model_rms_px = Rms(model_errors);
  fit.truth_rms_px = Rms(truth_errors);
  return fit;
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
