#include "core/scene_bundle.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>

#include <Eigen/Geometry>

namespace flysfm {
namespace {

// Images taken less than this apart are frames of one video: over so short
// an interval the camera's velocity is nearly constant, and their relative
// pose over their time apart is its motion while a frame's rows are read
// out. Photos taken further apart say nothing of that motion and are left as
// taken by a still camera. 0.1 s is a 10 Hz video's interval.
constexpr double kMaxVideoFrameInterval = 0.1;

// Each problem image's motion (BundleImage's velocities) from the registered
// images nearest before and after it in capture time, within
// kMaxVideoFrameInterval: the central difference of their poses, or the
// one-sided difference at a video's ends.
void SetVideoMotion(const Reconstruction& reconstruction,
                    const std::vector<image_t>& image_ids, BundleProblem* problem) {
  std::vector<std::pair<double, image_t>> by_time;
  for (const image_t id : reconstruction.RegisteredImageIds()) {
    const std::optional<double>& time = reconstruction.image(id).capture_time;
    if (time) by_time.emplace_back(*time, id);
  }
  std::sort(by_time.begin(), by_time.end());
  for (std::size_t i = 0; i < image_ids.size(); ++i) {
    const Image& image = reconstruction.image(image_ids[i]);
    if (!image.capture_time) continue;
    const auto it = std::lower_bound(by_time.begin(), by_time.end(),
                                     std::make_pair(*image.capture_time, image.image_id));
    if (it == by_time.end() || it->second != image.image_id) continue;
    auto before = it;
    if (it != by_time.begin() && it->first - std::prev(it)->first <= kMaxVideoFrameInterval) {
      before = std::prev(it);
    }
    auto after = it;
    if (std::next(it) != by_time.end() &&
        std::next(it)->first - it->first <= kMaxVideoFrameInterval) {
      after = std::next(it);
    }
    const double interval = after->first - before->first;
    if (!(interval > 0)) continue;
    // The later frame from the earlier one: to first order a rotation by
    // angle-axis w dt and a shift by v dt of the earlier frame's points.
    const Rigid3d after_from_before =
        *reconstruction.image(after->second).cam_from_world *
        Inverse(*reconstruction.image(before->second).cam_from_world);
    const Eigen::AngleAxisd rotation(after_from_before.rotation);
    problem->images[i].angular_velocity = rotation.angle() * rotation.axis() / interval;
    problem->images[i].linear_velocity = after_from_before.translation / interval;
  }
}

// Builds the problem over `weights`' images, solves it and writes back.
// `max_constant_observers`: per point, at most this many observations from
// constant images (0: all).
SceneBundleResult Adjust(const std::unordered_map<image_t, double>& weights,
                         const BundleAdjuster::Options& options, int max_constant_observers,
                         Reconstruction* reconstruction) {
  BundleProblem problem;
  std::map<camera_t, int> camera_index;
  std::map<image_t, int> image_index;
  std::unordered_map<point3D_t, int> point_index;
  std::vector<image_t> image_ids;
  std::vector<point3D_t> point_ids;

  const auto add_image = [&](image_t image_id, double weight) {
    const auto [it, inserted] = image_index.emplace(image_id, int(image_ids.size()));
    if (!inserted) return;
    const Image& image = reconstruction->image(image_id);
    const auto [cam_it, new_camera] =
        camera_index.emplace(image.camera_id, int(problem.cameras.size()));
    if (new_camera) problem.cameras.push_back(reconstruction->camera(image.camera_id));
    BundleImage bundle_image;
    bundle_image.camera = cam_it->second;
    bundle_image.cam_from_world = *image.cam_from_world;
    bundle_image.constant_pose = std::isinf(weight);
    bundle_image.weight = std::isinf(weight) ? 1.0 : weight;
    problem.images.push_back(bundle_image);
    image_ids.push_back(image_id);
  };

  // Free images first (in id order: the solve is deterministic), so that a
  // point's other observers can be appended.
  std::vector<image_t> free_ids;
  for (const auto& [image_id, weight] : weights) {
    if (!std::isinf(weight)) free_ids.push_back(image_id);
  }
  std::sort(free_ids.begin(), free_ids.end());
  for (const image_t image_id : free_ids) add_image(image_id, weights.at(image_id));
  const std::size_t num_free = image_ids.size();
  for (std::size_t i = 0; i < num_free; ++i) {
    const Image& image = reconstruction->image(image_ids[i]);
    for (const Point2D& point2D : image.points2D) {
      if (!point2D.HasPoint3D() ||
          !point_index.emplace(point2D.point3D_id, int(point_ids.size())).second) {
        continue;
      }
      point_ids.push_back(point2D.point3D_id);
    }
  }
  for (std::size_t p = 0; p < point_ids.size(); ++p) {
    const Point3D& point = reconstruction->point3D(point_ids[p]);
    problem.points.push_back(point.xyz);
    int num_constant = 0;
    for (const TrackElement& element : point.track) {
      const auto weight_it = weights.find(element.image_id);
      const double weight = weight_it == weights.end()
                                ? std::numeric_limits<double>::infinity()
                                : weight_it->second;
      if (std::isinf(weight) && max_constant_observers > 0 &&
          num_constant++ >= max_constant_observers) {
        continue;
      }
      add_image(element.image_id, weight);
      problem.observations.push_back(
          {image_index.at(element.image_id), int(p),
           reconstruction->image(element.image_id).points2D[element.point2D_idx].xy});
    }
  }

  SceneBundleResult result;
  if (num_free == 0 || problem.observations.empty()) return result;
  const bool rolling_shutter =
      options.refine_readout_time ||
      std::any_of(problem.cameras.begin(), problem.cameras.end(),
                  [](const Camera& camera) { return camera.readout_time != 0; });
  if (rolling_shutter) SetVideoMotion(*reconstruction, image_ids, &problem);
  result.summary = BundleAdjuster(options).Solve(&problem);
  if (!result.summary.IsSolutionUsable()) return result;

  for (std::size_t i = 0; i < image_ids.size(); ++i) {
    if (!problem.images[i].constant_pose) {
      reconstruction->SetPose(image_ids[i], problem.images[i].cam_from_world);
    }
  }
  for (std::size_t p = 0; p < point_ids.size(); ++p) {
    reconstruction->point3D(point_ids[p]).xyz = problem.points[p];
    reconstruction->MarkPointChanged(point_ids[p]);
  }
  if (rolling_shutter) {
    for (std::size_t i = 0; i < image_ids.size(); ++i) {
      Image& image = reconstruction->image(image_ids[i]);
      image.angular_velocity = problem.images[i].angular_velocity;
      image.linear_velocity = problem.images[i].linear_velocity;
    }
  }
  // Intrinsics held constant come back as they went: only a written change
  // is one (what follows a change, the quality measures, the view's
  // intrinsics, costs the model's size).
  bool cameras_changed = false;
  for (const auto& [camera_id, index] : camera_index) {
    Camera& camera = reconstruction->camera(camera_id);
    const Camera& solved = problem.cameras[index];
    if (camera.params != solved.params || camera.readout_time != solved.readout_time) {
      camera = solved;
      cameras_changed = true;
    }
  }
  if (cameras_changed) reconstruction->MarkCamerasChanged();
  result.points = std::move(point_ids);
  return result;
}

// Weight 1 each: a global problem.
std::unordered_map<image_t, double> EveryRegisteredImage(const Reconstruction& reconstruction) {
  std::unordered_map<image_t, double> weights;
  for (const image_t id : reconstruction.RegisteredImageIds()) weights[id] = 1.0;
  return weights;
}

}  // namespace

SceneBundleResult AdjustLocalBundle(const std::unordered_map<image_t, double>& weights,
                                    const BundleAdjuster::Options& options,
                                    int max_constant_observers,
                                    Reconstruction* reconstruction) {
  return Adjust(weights, options, max_constant_observers, reconstruction);
}

SceneBundleResult AdjustGlobalBundle(const BundleAdjuster::Options& options,
                                     Reconstruction* reconstruction) {
  return Adjust(EveryRegisteredImage(*reconstruction), options, 0, reconstruction);
}

OutlierSnooping SnoopOutliers(const std::unordered_map<image_t, double>& weights,
                              int max_constant_observers, double quantile, int max_rounds,
                              BundleAdjuster::Options options, double min_angle_deg,
                              Reconstruction* reconstruction) {
  // The quantile's error over the median error: sqrt(-2 ln(1 - q)) sigma
  // over sqrt(2 ln 2) sigma.
  const double quantile_over_median = std::sqrt(std::log(1 - quantile) / std::log(0.5));
  OutlierSnooping snooping;
  // The points the judged images observe: the only ones a drop concerns.
  const auto judged_points = [&snooping, reconstruction] {
    std::vector<point3D_t> points;
    for (const auto& [image_id, bound] : snooping.max_error_px) {
      for (const Point2D& point2D : reconstruction->image(image_id).points2D) {
        if (point2D.HasPoint3D()) points.push_back(point2D.point3D_id);
      }
    }
    std::sort(points.begin(), points.end());
    points.erase(std::unique(points.begin(), points.end()), points.end());
    return points;
  };
  for (const auto& [image_id, weight] : weights) {
    if (!std::isfinite(weight)) continue;
    const Image& image = reconstruction->image(image_id);
    std::vector<double> errors;
    errors.reserve(std::size_t(image.num_points3D));
    for (point2D_t idx = 0; idx < image.points2D.size(); ++idx) {
      const Point2D& point2D = image.points2D[idx];
      if (!point2D.HasPoint3D()) continue;
      errors.push_back(reconstruction->ReprojectionError(
          image_id, idx, reconstruction->point3D(point2D.point3D_id).xyz));
    }
    if (errors.empty()) continue;
    const auto median = errors.begin() + std::ptrdiff_t(errors.size() / 2);
    std::nth_element(errors.begin(), median, errors.end());
    snooping.max_error_px[image_id] = *median * quantile_over_median;
  }
  snooping.num_removed =
      reconstruction->FilterPoints3D(judged_points(), snooping.max_error_px, min_angle_deg);
  options.refine_focal_length = false;
  options.refine_principal_point = false;
  options.refine_extra_params = false;
  options.refine_readout_time = false;
  std::size_t removed = snooping.num_removed;
  while (removed > 0 && snooping.num_rounds < max_rounds) {
    snooping.summary =
        AdjustLocalBundle(weights, options, max_constant_observers, reconstruction).summary;
    ++snooping.num_rounds;
    // An adjustment that gave way (should_stop) is short of its optimum,
    // where errors it would have taken within their bound are still beyond.
    if (!snooping.summary.IsSolutionUsable() || (options.should_stop && options.should_stop())) {
      break;
    }
    removed =
        reconstruction->FilterPoints3D(judged_points(), snooping.max_error_px, min_angle_deg);
    snooping.num_removed += removed;
  }
  return snooping;
}

OutlierSnooping SnoopOutliers(double quantile, int max_rounds,
                              const BundleAdjuster::Options& options, double min_angle_deg,
                              Reconstruction* reconstruction) {
  return SnoopOutliers(EveryRegisteredImage(*reconstruction), 0, quantile, max_rounds, options,
                       min_angle_deg, reconstruction);
}

}  // namespace flysfm
