#include "tests/testing/ground_path.h"

#include <algorithm>
#include <cmath>
#include <random>
#include <unordered_map>

namespace flysfm::testing {

SyntheticScene MakeGroundPathScene(const GroundPathSceneOptions& options) {
  std::mt19937 rng(options.seed);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  std::normal_distribution<double> noise(0.0, options.noise_px);
  const Camera& camera = options.camera;

  SyntheticScene scene;
  scene.camera = camera;
  const int num_strips =
      (options.num_images + options.images_per_strip - 1) / options.images_per_strip;
  for (int i = 0; i < options.num_images; ++i) {
    const int strip = i / options.images_per_strip;
    const int along = i % options.images_per_strip;
    const bool forward = strip % 2 == 0;
    const int step = forward ? along : options.images_per_strip - 1 - along;
    const Eigen::Vector3d center(step * options.image_spacing,
                                 strip * options.strip_spacing, options.altitude);
    // Nadir view, image x along the flight direction.
    const double heading = forward ? 1.0 : -1.0;
    Eigen::Matrix3d world_from_cam;
    world_from_cam.col(0) = Eigen::Vector3d(heading, 0, 0);
    world_from_cam.col(1) = Eigen::Vector3d(0, -heading, 0);
    world_from_cam.col(2) = Eigen::Vector3d(0, 0, -1);
    const Eigen::Matrix3d cam_from_world =
        RandomRotationOfAngle(rng, options.max_tilt_deg * unit(rng))
            .toRotationMatrix() *
        world_from_cam.transpose();
    scene.cams_from_world.emplace_back(cam_from_world, -cam_from_world * center);
  }

  // Ground extent: the path plus a footprint's half-size (at the lowest
  // terrain) on every side.
  const double focal = camera.MeanFocalLength();
  const double reach = (options.altitude + options.relief) * 0.5 *
                       std::max(camera.width, camera.height) / focal;
  const double x_max = (options.images_per_strip - 1) * options.image_spacing;
  const double y_max = (num_strips - 1) * options.strip_spacing;
  const double width = x_max + 2 * reach;
  const double height = y_max + 2 * reach;
  const int num_points =
      static_cast<int>(std::lround(options.point_density * width * height));
  for (int p = 0; p < num_points; ++p) {
    const double x = -reach + width * unit(rng);
    const double y = -reach + height * unit(rng);
    const double z = options.relief * std::sin(0.37 * x + 1.3) * std::cos(0.23 * y);
    scene.points.emplace_back(x, y, z);
  }

  // Bin the points on a grid so that each image only tests its neighbourhood.
  const double cell = reach;
  const int cells_x = static_cast<int>(std::ceil(width / cell)) + 1;
  const int cells_y = static_cast<int>(std::ceil(height / cell)) + 1;
  std::vector<std::vector<int>> grid(cells_x * cells_y);
  auto cell_of = [&](double v, double origin, int cells) {
    return std::clamp(static_cast<int>((v - origin) / cell), 0, cells - 1);
  };
  for (int p = 0; p < num_points; ++p) {
    grid[cell_of(scene.points[p].y(), -reach, cells_y) * cells_x +
         cell_of(scene.points[p].x(), -reach, cells_x)]
        .push_back(p);
  }
  for (int i = 0; i < options.num_images; ++i) {
    const Rigid3d& pose = scene.cams_from_world[i];
    const Eigen::Vector3d center = ProjectionCenter(pose);
    std::vector<std::pair<int, Eigen::Vector2d>> seen;
    for (int cy = cell_of(center.y() - 1.5 * reach, -reach, cells_y);
         cy <= cell_of(center.y() + 1.5 * reach, -reach, cells_y); ++cy) {
      for (int cx = cell_of(center.x() - 1.5 * reach, -reach, cells_x);
           cx <= cell_of(center.x() + 1.5 * reach, -reach, cells_x); ++cx) {
        for (const int p : grid[cy * cells_x + cx]) {
          const Eigen::Vector3d in_cam = pose * scene.points[p];
          if (in_cam.z() <= 1e-6) continue;
          const Eigen::Vector2d pixel = camera.ImgFromCam(in_cam);
          if (pixel.x() < 0 || pixel.y() < 0 || pixel.x() >= camera.width ||
              pixel.y() >= camera.height) {
            continue;
          }
          seen.emplace_back(p, pixel);
        }
      }
    }
    std::sort(seen.begin(), seen.end(),
              [](const auto& a, const auto& b) { return a.first < b.first; });
    for (auto& [p, pixel] : seen) {
      if (options.noise_px > 0) pixel += Eigen::Vector2d(noise(rng), noise(rng));
      scene.observations.push_back({i, p, pixel});
    }
  }
  return scene;
}

std::vector<std::vector<int>> RankByCovisibility(const SyntheticScene& scene,
                                                 int max_neighbours) {
  const int num_images = static_cast<int>(scene.cams_from_world.size());
  std::vector<std::vector<int>> observers(scene.points.size());
  for (const SyntheticObservation& obs : scene.observations) {
    observers[obs.point].push_back(obs.image);
  }
  std::vector<std::unordered_map<int, int>> shared(num_images);
  for (const std::vector<int>& images : observers) {
    for (const int a : images) {
      for (const int b : images) {
        if (a != b) ++shared[a][b];
      }
    }
  }
  std::vector<std::vector<int>> ranked(num_images);
  for (int i = 0; i < num_images; ++i) {
    std::vector<std::pair<int, int>> counts(shared[i].begin(), shared[i].end());
    std::sort(counts.begin(), counts.end(), [](const auto& a, const auto& b) {
      return a.second != b.second ? a.second > b.second : a.first < b.first;
    });
    for (int j = 0; j < std::min<int>(max_neighbours, counts.size()); ++j) {
      ranked[i].push_back(counts[j].first);
    }
  }
  return ranked;
}

}  // namespace flysfm::testing
