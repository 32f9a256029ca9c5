#include "io/run/run_writer.h"

#include <algorithm>
#include <fstream>
#include <map>
#include <optional>
#include <stdexcept>

#include "io/formats/atomic_file.h"
#include "io/formats/colmap_model.h"
#include "io/formats/ply.h"
#include "io/formats/trajectory.h"

namespace flysfm {
namespace {

double Percentile(std::vector<double> values, double fraction) {
  if (values.empty()) return 0;
  std::sort(values.begin(), values.end());
  const double position = fraction * (values.size() - 1);
  const std::size_t below = std::size_t(position);
  const std::size_t above = std::min(below + 1, values.size() - 1);
  return values[below] + (position - below) * (values[above] - values[below]);
}

}  // namespace

nlohmann::json ToJson(const Engine::RefinementTotals& totals) {
  return {{"slices", totals.num_slices},
          {"pairs_tried", totals.num_pairs_tried},
          {"pairs_verified", totals.num_pairs_verified},
          {"pairs_linked", totals.num_pairs_linked},
          {"global_bas", totals.num_global_bas},
          {"snooped_observations", totals.num_snooped},
          {"ms", totals.ms}};
}

namespace {

// A sigma, or null when undefined (JSON has no infinity).
nlohmann::json SigmaJson(const std::optional<double>& sigma) {
  return sigma ? nlohmann::json(*sigma) : nlohmann::json(nullptr);
}

}  // namespace

nlohmann::json ToJson(const Coverage& coverage) {
  const Coverage::Summary& summary = coverage.summary();
  const Coverage::Options& options = coverage.options();
  const auto vector = [](const Eigen::Vector3d& v) { return nlohmann::json{v.x(), v.y(), v.z()}; };
  nlohmann::json suggestions = nlohmann::json::array();
  for (const Coverage::Suggestion& suggestion : coverage.suggestions()) {
    const Eigen::Quaterniond& q = suggestion.cam_from_world.rotation;
    suggestions.push_back({{"position", vector(suggestion.position)},
                           {"direction", vector(suggestion.direction)},
                           {"cam_from_world",
                            {{"qw", q.w()}, {"qx", q.x()}, {"qy", q.y()}, {"qz", q.z()},
                             {"t", vector(suggestion.cam_from_world.translation)}}},
                           {"area_share", suggestion.area_share},
                           {"step", suggestion.step},
                           {"reason", suggestion.reason}});
  }
  return {{"min_views", options.min_views},
          {"min_angle_deg", options.min_angle_deg},
          {"max_incidence_deg", options.max_incidence_deg},
          {"points_used", summary.points_used},
          {"rays", summary.rays},
          {"faces", summary.faces},
          {"area", summary.area},
          {"well_covered_area", summary.well_covered_area},
          {"narrow_angle_area", summary.narrow_angle_area},
          {"few_views_area", summary.few_views_area},
          {"underside_area", summary.underside_area},
          {"out_of_reach_area", summary.out_of_reach_area},
          {"well_covered_share", summary.well_covered_share},
          {"median_gsd", summary.median_gsd},
          {"up", vector(coverage.up())},
          {"ms", summary.ms},
          {"suggestions", suggestions}};
}

nlohmann::json ToJson(const QualityTracker& quality, const Reconstruction& reconstruction) {
  const QualityTracker::Summary summary = quality.Summarize();
  const QualityTracker::Options& options = quality.options();
  nlohmann::json images = nlohmann::json::array();
  for (const auto& [image_id, image] : quality.Images()) {
    images.push_back({{"name", reconstruction.image(image_id).name},
                      {"inliers", image.inliers},
                      {"spread", image.spread},
                      {"center_sigma", SigmaJson(image.center_sigma)}});
  }
  return {
      {"sigma_px", summary.sigma_px},
      {"sigma_source", SigmaSourceName(options.sigma_source)},
      {"prior_redundancy", options.prior_redundancy},
      {"min_views", options.min_views},
      {"min_angle_deg", options.min_angle_deg},
      {"points", summary.points},
      {"well_covered_points", summary.well_covered_points},
      {"well_covered_share", summary.well_covered_share},
      {"median_views", summary.median_views},
      {"median_max_angle_deg", summary.median_max_angle_deg},
      {"median_error_px", summary.median_error_px},
      {"median_point_sigma", summary.median_point_sigma},
      {"undefined_point_sigmas", summary.undefined_point_sigmas},
      {"images", summary.images},
      {"median_inliers", summary.median_inliers},
      {"median_spread", summary.median_spread},
      {"median_center_sigma", summary.median_center_sigma},
      {"undefined_center_sigmas", summary.undefined_center_sigmas},
      {"updates", summary.updates},
      {"recomputed_points", summary.recomputed_points},
      {"recomputed_images", summary.recomputed_images},
      {"deferred_points", summary.deferred_points},
      {"deferred_images", summary.deferred_images},
      {"update_ms", summary.update_ms},
      {"per_image", images}};
}

nlohmann::json ToJson(const ImageResult& result) {
  nlohmann::json json = {
      {"name", result.name},
      {"status", ImageStatusName(result.status)},
      {"features", result.num_features},
      {"candidates", result.num_candidates},
      {"verified_pairs", result.num_verified_pairs},
      {"lsm_rejected", result.num_lsm_rejected},
      {"correspondences", result.num_correspondences},
      {"densified", result.num_densified},
      {"pose_inliers", result.num_pose_inliers},
      {"new_points", result.num_new_points},
      {"merged_points", result.num_merged_points},
      {"completed", result.num_completed},
      {"observations", result.num_observations},
      {"ba", {{"free_images", result.ba_free_images},
              {"images", result.ba_images},
              {"points", result.ba_points},
              {"iterations", result.ba_iterations},
              {"global", result.global_ba},
              {"global_iterations", result.global_ba_iterations}}},
      {"model_images", result.model_images},
      {"model_points", result.model_points},
      {"models", result.num_models}};
  if (result.image_id != kInvalidImageId) json["image_id"] = result.image_id;
  if (result.model_id != kInvalidModelId) json["model"] = result.model_id;
  if (result.num_posed_in_others > 0) json["posed_in_other_models"] = result.num_posed_in_others;
  if (result.num_merged_models > 0) json["merged_models"] = result.num_merged_models;
  if (!result.reason.empty()) json["reason"] = result.reason;
  if (result.focal_length_from_pairs) {
    json["focal_length_from_pairs"] = *result.focal_length_from_pairs;
  }
  if (result.cam_from_world) {
    const Rigid3d& pose = *result.cam_from_world;
    json["cam_from_world"] = {
        {"qw", pose.rotation.w()}, {"qx", pose.rotation.x()},
        {"qy", pose.rotation.y()}, {"qz", pose.rotation.z()},
        {"tx", pose.translation.x()}, {"ty", pose.translation.y()},
        {"tz", pose.translation.z()}};
  }
  nlohmann::json times;
  for (const auto& [name, member] : StageTimes::Stages()) times[name] = result.times.*member;
  times["total"] = result.times.total;
  json["ms"] = times;
  return json;
}

nlohmann::json StageTimeStatistics(const std::vector<ImageResult>& results) {
  nlohmann::json json;
  std::vector<StageTimes::Stage> stages = StageTimes::Stages();
  stages.emplace_back("total", &StageTimes::total);
  for (const auto& [name, member] : stages) {
    std::vector<double> values;
    for (const ImageResult& result : results) {
      if (result.status != ImageStatus::kRejected) values.push_back(result.times.*member);
    }
    json[name] = {{"median", Percentile(values, 0.5)}, {"p95", Percentile(values, 0.95)}};
  }
  return json;
}

RunWriter::RunWriter(const std::filesystem::path& out_dir) : dir_(out_dir) {
  std::filesystem::create_directories(dir_);
  log_.open(dir_ / "log.jsonl", std::ios::app);
  if (!log_) throw std::runtime_error("cannot write " + (dir_ / "log.jsonl").string());
  std::ifstream previous(dir_ / "summary.json");
  const nlohmann::json summary = nlohmann::json::parse(previous, nullptr, false);
  const auto registered = summary.find("registered");
  if (registered != summary.end() && registered->is_number_unsigned()) {
    previous_registered_ = registered->get<std::size_t>();
  }
}

bool RunWriter::MayReplaceOutputs(const Reconstruction& reconstruction, bool final) {
  if (reconstruction.NumRegisteredImages() < previous_registered_) {
    if (!final) return false;
    namespace fs = std::filesystem;
    const fs::path previous = dir_ / "previous";
    fs::remove_all(previous);
    fs::create_directories(previous);
    for (const char* name : {"sparse", "points.ply", "trajectory.txt", "summary.json"}) {
      if (fs::exists(dir_ / name)) fs::rename(dir_ / name, previous / name);
    }
  }
  previous_registered_ = 0;
  return true;
}

void RunWriter::Log(const ImageResult& result, const std::string& source,
                    std::optional<double> quality_ms, std::optional<double> coverage_ms) {
  nlohmann::json record = ToJson(result);
  if (!source.empty()) record["source"] = source;
  if (quality_ms) record["ms"]["quality"] = *quality_ms;
  if (coverage_ms) record["ms"]["coverage"] = *coverage_ms;
  // One whole line per write, flushed: a reader tailing the log never sees
  // half a record, and a crash loses none that was reported.
  log_ << record.dump() + "\n" << std::flush;
}

void RunWriter::WriteModel(const Reconstruction& reconstruction,
                           const QualityTracker* quality, const Coverage* coverage) {
  namespace fs = std::filesystem;
  // The largest sub-model where a reader expects the model; each other one,
  // in a frame of its own, a COLMAP model in sparse/1, sparse/2, ...
  const auto models = reconstruction.Models();
  std::optional<Reconstruction> largest;
  if (models.size() > 1) largest = reconstruction.SubModel(models.front().first);
  const Reconstruction& model = largest ? *largest : reconstruction;
  WriteColmapModel(model, dir_ / "sparse");
  for (std::size_t i = 1;; ++i) {
    const fs::path dir = dir_ / "sparse" / std::to_string(i);
    if (i < models.size()) {
      WriteColmapModel(reconstruction.SubModel(models[i].first), dir);
    } else if (fs::exists(dir)) {
      fs::remove_all(dir);  // merged since the last write
    } else {
      break;
    }
  }
  if (coverage) WriteSurfacePly(*coverage, dir_ / "surface.ply");
  if (quality) {
    const std::unordered_map<point3D_t, PointQuality> points = quality->Points();
    WritePly(model, dir_ / "points.ply", &points);
  } else {
    WritePly(model, dir_ / "points.ply");
  }
  WriteTumTrajectory(TrajectoryOf(model), dir_ / "trajectory.txt");
}

void RunWriter::WriteSummary(const Reconstruction& reconstruction,
                             const std::vector<ImageResult>& results,
                             const RunCounts& counts,
                             const std::vector<std::string>& pending,
                             double wall_seconds, const QualityTracker* quality,
                             const Coverage* coverage) {
  int rejected = 0;
  for (const ImageResult& result : results) rejected += result.status == ImageStatus::kRejected;
  // The cameras as the model ends with them, with what COLMAP's format has no
  // place for: a rolling shutter's readout time (0: global shutter or still).
  nlohmann::json cameras = nlohmann::json::array();
  for (const auto& [camera_id, camera] : reconstruction.cameras()) {
    cameras.push_back({{"id", camera_id},
                       {"model", CameraModelName(camera.model_id)},
                       {"width", camera.width},
                       {"height", camera.height},
                       {"params", camera.params},
                       {"readout_time_s", camera.readout_time}});
  }
  nlohmann::json summary = {
      {"images_in", counts.images_in},
      {"registered", reconstruction.NumRegisteredImages()},
      {"rejected", rejected},
      {"pending", pending},
      {"quarantined", counts.quarantined},
      {"engine_errors", counts.engine_errors},
      {"write_errors", counts.write_errors},
      {"skipped_entries", counts.skipped_entries},
      {"resumed_images", counts.resumed_images},
      {"skipped_in_model", counts.in_model},
      {"checkpoint_ms", counts.checkpoint_ms},
      {"refinement", ToJson(counts.refinement)},
      {"cameras", cameras},
      {"points", reconstruction.NumPoints3D()},
      {"observations", reconstruction.NumObservations()},
      {"mean_reprojection_error_px", reconstruction.MeanReprojectionError()},
      {"mean_track_length", reconstruction.MeanTrackLength()},
      {"wall_seconds", wall_seconds},
      {"stage_ms", StageTimeStatistics(results)}};
  // Each sub-model, the largest first (the one in sparse/).
  nlohmann::json models = nlohmann::json::array();
  std::map<model_t, std::size_t> points_in;
  for (const auto& [id, point] : reconstruction.points3D()) {
    ++points_in[reconstruction.ModelOfPoint(id)];
  }
  for (const auto& [model_id, images] : reconstruction.Models()) {
    models.push_back({{"id", model_id}, {"images", images.size()}, {"points", points_in[model_id]}});
  }
  summary["models"] = models;
  if (!counts.sources.empty()) {
    nlohmann::json sources = nlohmann::json::array();
    for (const SourceCounts& source : counts.sources) {
      sources.push_back({{"tag", source.tag},
                         {"images_in", source.images_in},
                         {"registered", source.registered},
                         {"rejected", source.rejected},
                         {"pending", source.pending}});
    }
    summary["sources"] = sources;
  }
  if (quality) summary["quality"] = ToJson(*quality, reconstruction);
  if (coverage) summary["coverage"] = ToJson(*coverage);
  WriteFileAtomically(dir_ / "summary.json",
                      [&](std::ostream& out) { out << summary.dump(2) << "\n"; });
}

}  // namespace flysfm
