#include "tests/testing/synthetic.h"

#include <cmath>

namespace flysfm::testing {

Eigen::Vector3d RandomUnitVector(std::mt19937& rng) {
  std::normal_distribution<double> normal(0.0, 1.0);
  Eigen::Vector3d v(normal(rng), normal(rng), normal(rng));
  while (v.norm() < 1e-9) v = Eigen::Vector3d(normal(rng), normal(rng), normal(rng));
  return v.normalized();
}

Eigen::Quaterniond RandomRotation(std::mt19937& rng) {
  std::normal_distribution<double> normal(0.0, 1.0);
  Eigen::Quaterniond q(normal(rng), normal(rng), normal(rng), normal(rng));
  return q.normalized();
}

Eigen::Quaterniond RandomRotationOfAngle(std::mt19937& rng, double angle_deg) {
  return Eigen::Quaterniond(
      Eigen::AngleAxisd(angle_deg * M_PI / 180.0, RandomUnitVector(rng)));
}

std::vector<SyntheticObservation> SyntheticScene::ObservationsOf(int image) const {
  std::vector<SyntheticObservation> result;
  for (const auto& obs : observations) {
    if (obs.image == image) result.push_back(obs);
  }
  return result;
}

SyntheticScene MakeSyntheticScene(const SyntheticSceneOptions& options) {
  std::mt19937 rng(options.seed);
  std::uniform_real_distribution<double> uniform(-1.0, 1.0);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  std::normal_distribution<double> noise(0.0, options.noise_px);

  SyntheticScene scene;
  scene.camera = options.camera;
  for (int i = 0; i < options.num_points; ++i) {
    const double s = options.scene_half_size;
    scene.points.emplace_back(s * uniform(rng), s * uniform(rng),
                              options.planar ? 0.0 : s * uniform(rng));
  }
  for (int i = 0; i < options.num_images; ++i) {
    const double fraction =
        options.num_images > 1 ? double(i) / (options.num_images - 1) - 0.5 : 0.0;
    const double angle = fraction * options.arc_deg * M_PI / 180.0;
    // On a circle in the x-z plane, at negative z, looking towards +z.
    const Eigen::Vector3d center(options.camera_distance * std::sin(angle),
                                 0.3 * options.scene_half_size * uniform(rng),
                                 -options.camera_distance * std::cos(angle));
    const Eigen::Vector3d forward = (-center).normalized();
    const Eigen::Vector3d right = Eigen::Vector3d::UnitY().cross(forward).normalized();
    const Eigen::Vector3d down = forward.cross(right);
    Eigen::Matrix3d world_from_cam_rotation;
    world_from_cam_rotation << right, down, forward;
    const Eigen::Quaterniond tilt =
        RandomRotationOfAngle(rng, options.max_tilt_deg * unit(rng));
    const Eigen::Matrix3d cam_from_world_rotation =
        tilt.toRotationMatrix() * world_from_cam_rotation.transpose();
    scene.cams_from_world.emplace_back(cam_from_world_rotation,
                                       -cam_from_world_rotation * center);
  }
  for (int i = 0; i < options.num_images; ++i) {
    for (int p = 0; p < options.num_points; ++p) {
      const Eigen::Vector3d in_cam = scene.cams_from_world[i] * scene.points[p];
      if (in_cam.z() <= 1e-6) continue;
      Eigen::Vector2d pixel = scene.camera.ImgFromCam(in_cam);
      if (pixel.x() < 0 || pixel.y() < 0 || pixel.x() >= scene.camera.width ||
          pixel.y() >= scene.camera.height) {
        continue;
      }
      if (options.noise_px > 0) pixel += Eigen::Vector2d(noise(rng), noise(rng));
      scene.observations.push_back({i, p, pixel});
    }
  }
  return scene;
}

}  // namespace flysfm::testing
