#include "core/scene_bundle.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>

namespace flysfm {
namespace {

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
  result.summary = BundleAdjuster(options).Solve(&problem);
  if (!result.summary.IsSolutionUsable()) return result;

  for (std::size_t i = 0; i < image_ids.size(); ++i) {
    if (!problem.images[i].constant_pose) {
      reconstruction->RegisterImage(image_ids[i], problem.images[i].cam_from_world);
    }
  }
  for (std::size_t p = 0; p < point_ids.size(); ++p) {
    reconstruction->point3D(point_ids[p]).xyz = problem.points[p];
    reconstruction->MarkPointChanged(point_ids[p]);
  }
  for (const auto& [camera_id, index] : camera_index) {
    reconstruction->camera(camera_id) = problem.cameras[index];
  }
  if (!camera_index.empty()) reconstruction->MarkCamerasChanged();
  result.points = std::move(point_ids);
  return result;
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
  std::unordered_map<image_t, double> weights;
  for (const image_t id : reconstruction->RegisteredImageIds()) weights[id] = 1.0;
  return Adjust(weights, options, 0, reconstruction);
}

}  // namespace flysfm
