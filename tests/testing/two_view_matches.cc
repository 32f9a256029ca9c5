#include "tests/testing/two_view_matches.h"

#include <random>

#include "tests/testing/synthetic.h"

namespace flysfm::testing {

Rigid3d TwoViewMatches::Cam2FromCam1() const {
  return cam2_from_world * Inverse(cam1_from_world);
}

int TwoViewMatches::NumInliers() const {
  int count = 0;
  for (const char flag : is_inlier) count += flag != 0;
  return count;
}

TwoViewMatches MakeTwoViewMatches(const TwoViewMatchesOptions& options) {
  std::mt19937 rng(options.seed);
  SyntheticSceneOptions scene_options;
  scene_options.num_images = 2;
  // Enough candidates that num_matches of them are seen by both cameras.
  scene_options.num_points = 4 * options.num_matches + 50;
  scene_options.arc_deg = options.arc_deg;
  scene_options.camera_distance = options.camera_distance;
  scene_options.planar = options.scene == TwoViewScene::kPlanar;
  scene_options.camera = options.camera;
  scene_options.seed = options.seed;
  const SyntheticScene scene = MakeSyntheticScene(scene_options);

  TwoViewMatches matches;
  matches.camera = options.camera;
  matches.cam1_from_world = scene.cams_from_world[0];
  matches.cam2_from_world = scene.cams_from_world[1];
  if (options.scene == TwoViewScene::kPureRotation) {
    // Turn the first camera about its centre.
    std::uniform_real_distribution<double> angle(5.0, 15.0);
    const Eigen::Quaterniond turn = RandomRotationOfAngle(rng, angle(rng));
    matches.cam2_from_world =
        Rigid3d(turn, Eigen::Vector3d::Zero()) * matches.cam1_from_world;
  }
  std::normal_distribution<double> noise(0.0, options.noise_px);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  const Camera& camera = options.camera;
  auto visible = [&](const Rigid3d& pose, const Eigen::Vector3d& point,
                     Eigen::Vector2d* pixel) {
    const Eigen::Vector3d in_cam = pose * point;
    if (in_cam.z() <= 1e-6) return false;
    *pixel = camera.ImgFromCam(in_cam);
    return pixel->x() >= 0 && pixel->y() >= 0 && pixel->x() < camera.width &&
           pixel->y() < camera.height;
  };
  for (const Eigen::Vector3d& point : scene.points) {
    if (static_cast<int>(matches.points1.size()) == options.num_matches) break;
    Eigen::Vector2d x1, x2;
    if (!visible(matches.cam1_from_world, point, &x1) ||
        !visible(matches.cam2_from_world, point, &x2)) {
      continue;
    }
    if (options.noise_px > 0) {
      x1 += Eigen::Vector2d(noise(rng), noise(rng));
      x2 += Eigen::Vector2d(noise(rng), noise(rng));
    }
    matches.points1.push_back(x1);
    matches.points2.push_back(x2);
    matches.points3D.push_back(point);
    matches.is_inlier.push_back(1);
  }
  const int n = static_cast<int>(matches.points1.size());
  const int num_outliers = static_cast<int>(options.outlier_ratio * n + 0.5);
  for (int k = 0; k < num_outliers; ++k) {
    // A random match becomes an outlier (partial Fisher-Yates).
    std::uniform_int_distribution<int> pick(k, n - 1);
    const int j = pick(rng);
    std::swap(matches.points1[k], matches.points1[j]);
    std::swap(matches.points2[k], matches.points2[j]);
    std::swap(matches.points3D[k], matches.points3D[j]);
    matches.points2[k] = Eigen::Vector2d(unit(rng) * camera.width,
                                         unit(rng) * camera.height);
    matches.is_inlier[k] = 0;
  }
  // Shuffle, so that outliers are not all first.
  for (int i = n - 1; i > 0; --i) {
    std::uniform_int_distribution<int> pick(0, i);
    const int j = pick(rng);
    std::swap(matches.points1[i], matches.points1[j]);
    std::swap(matches.points2[i], matches.points2[j]);
    std::swap(matches.points3D[i], matches.points3D[j]);
    std::swap(matches.is_inlier[i], matches.is_inlier[j]);
  }
  return matches;
}

double InlierClassificationRate(const std::vector<char>& estimated,
                                const std::vector<char>& truth) {
  if (estimated.size() != truth.size() || truth.empty()) return 0.0;
  int agree = 0;
  for (std::size_t i = 0; i < truth.size(); ++i) {
    agree += (estimated[i] != 0) == (truth[i] != 0);
  }
  return static_cast<double>(agree) / truth.size();
}

}  // namespace flysfm::testing
