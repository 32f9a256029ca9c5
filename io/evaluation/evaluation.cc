#include "io/evaluation/evaluation.h"

#include <algorithm>
#include <cmath>
#include <sstream>

#include <nlohmann/json.hpp>

#include "geometry/similarity.h"
#include "geometry/triangulation.h"

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

namespace {

struct View {
  const Camera* camera;
  Rigid3d cam_from_world;
  Eigen::Vector2d pixel;
};

double Median(std::vector<double> values) {
  const auto middle = values.begin() + values.size() / 2;
  std::nth_element(values.begin(), middle, values.end());
  return *middle;
}

double Rms(const std::vector<double>& values) {
  double sum = 0;
  for (const double v : values) sum += v * v;
  return std::sqrt(sum / values.size());
}

Eigen::Vector2d Residual(const View& view, const Eigen::Vector3d& point) {
  return view.camera->ImgFromCam(view.cam_from_world * point) - view.pixel;
}

// The DLT's point, then Gauss-Newton on the reprojection errors (numeric
// derivatives: a few views, a few iterations); nullopt where a view has it
// behind the camera.
std::optional<Eigen::Vector3d> TriangulateInPixels(const std::vector<View>& views) {
  std::vector<Matrix3x4d> matrices;
  std::vector<Eigen::Vector2d> normalized;
  for (const View& view : views) {
    matrices.push_back(view.cam_from_world.ToMatrix());
    normalized.push_back(view.camera->CamFromImg(view.pixel));
  }
  std::optional<Eigen::Vector3d> point = TriangulateMultiViewPoint(matrices, normalized);
  if (!point) return std::nullopt;
  for (int iteration = 0; iteration < 10; ++iteration) {
    Eigen::Matrix3d normal = Eigen::Matrix3d::Zero();
    Eigen::Vector3d gradient = Eigen::Vector3d::Zero();
    for (const View& view : views) {
      if ((view.cam_from_world * *point).z() <= 0) return std::nullopt;
      const Eigen::Vector2d residual = Residual(view, *point);
      Eigen::Matrix<double, 2, 3> jacobian;
      const double step = 1e-6 * std::max(1.0, point->norm());
      for (int k = 0; k < 3; ++k) {
        Eigen::Vector3d plus = *point, minus = *point;
        plus[k] += step;
        minus[k] -= step;
        jacobian.col(k) = (Residual(view, plus) - Residual(view, minus)) / (2 * step);
      }
      normal += jacobian.transpose() * jacobian;
      gradient += jacobian.transpose() * residual;
    }
    const Eigen::Vector3d delta = normal.ldlt().solve(-gradient);
    if (!delta.allFinite()) return std::nullopt;
    *point += delta;
    if (delta.norm() < 1e-12 * std::max(1.0, point->norm())) break;
  }
  return point;
}

}  // namespace

std::optional<PoseFit> FitObservationsToPoses(
    const Reconstruction& reconstruction,
    const std::map<std::string, Rigid3d>& true_cam_from_world) {
  std::vector<double> model_errors, truth_errors;
  for (const auto& [point3D_id, point3D] : reconstruction.points3D()) {
    std::vector<View> views;
    std::vector<double> own;
    for (const TrackElement& element : point3D.track) {
      const Image& image = reconstruction.image(element.image_id);
      const auto truth = true_cam_from_world.find(image.name);
      if (truth == true_cam_from_world.end()) continue;
      views.push_back({&reconstruction.camera(image.camera_id), truth->second,
                       image.points2D[element.point2D_idx].xy});
      own.push_back(reconstruction.ReprojectionError(element.image_id, element.point2D_idx, point3D.xyz));
    }
    if (views.size() < 2) continue;
    const std::optional<Eigen::Vector3d> point = TriangulateInPixels(views);
    if (!point) continue;
    for (std::size_t i = 0; i < views.size(); ++i) {
      model_errors.push_back(own[i]);
      truth_errors.push_back(Residual(views[i], *point).norm());
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
