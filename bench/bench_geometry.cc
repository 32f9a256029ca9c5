// Times the robust estimators of geometry/ on synthetic data with exact
// ground truth: F, E and H RANSAC on 2000 matches with 50 % outliers, and
// absolute pose RANSAC (P3P samples, EPnP + LM local optimisation) on 1000
// 2D-3D matches with 50 % outliers. 0.5 px noise throughout. Prints the
// median wall and CPU time of each over several runs and one final line of
// JSON.

#include <algorithm>
#include <chrono>
#include <ctime>
#include <cstdio>
#include <functional>
#include <random>
#include <vector>

#include "geometry/absolute_pose.h"
#include "geometry/two_view_geometry.h"
#include "tests/testing/two_view_matches.h"

namespace {

using flysfm::testing::TwoViewMatches;

constexpr int kRuns = 15;

struct Timing {
  double wall_ms;  // median wall time
  double cpu_ms;   // median CPU time of this process (one thread): closer
                   // to the unloaded figure when other jobs share the cores
};

double Median(std::vector<double> values) {
  std::nth_element(values.begin(), values.begin() + values.size() / 2, values.end());
  return values[values.size() / 2];
}

// Times `run` (which gets the run index as the RANSAC seed); `inliers`
// receives the inlier count of the last run.
Timing Time(const std::function<int(int)>& run, int* inliers) {
  std::vector<double> wall, cpu;
  for (int i = 0; i < kRuns; ++i) {
    const auto start = std::chrono::steady_clock::now();
    const std::clock_t cpu_start = std::clock();
    *inliers = run(i);
    cpu.push_back(1000.0 * (std::clock() - cpu_start) / CLOCKS_PER_SEC);
    wall.push_back(std::chrono::duration<double, std::milli>(
                       std::chrono::steady_clock::now() - start).count());
  }
  return {Median(wall), Median(cpu)};
}

TwoViewMatches Matches(flysfm::testing::TwoViewScene scene, int num_matches) {
  flysfm::testing::TwoViewMatchesOptions options;
  options.scene = scene;
  options.num_matches = num_matches;
  options.outlier_ratio = 0.5;
  options.noise_px = 0.5;
  options.seed = 1;
  return flysfm::testing::MakeTwoViewMatches(options);
}

}  // namespace

int main() {
  using namespace flysfm;
  const TwoViewMatches general = Matches(testing::TwoViewScene::kGeneral, 2000);
  const TwoViewMatches planar = Matches(testing::TwoViewScene::kPlanar, 2000);
  RansacOptions options;
  options.max_error = 2.0;

  int f_inliers = 0, e_inliers = 0, h_inliers = 0, pose_inliers = 0;
  const Timing f_time = Time([&](int seed) {
    RansacOptions o = options;
    o.seed = seed;
    return EstimateFundamentalMatrix(general.points1, general.points2, o).num_inliers;
  }, &f_inliers);

  std::vector<Eigen::Vector2d> x1, x2;
  for (std::size_t i = 0; i < general.points1.size(); ++i) {
    x1.push_back(general.camera.CamFromImg(general.points1[i]));
    x2.push_back(general.camera.CamFromImg(general.points2[i]));
  }
  const Timing e_time = Time([&](int seed) {
    RansacOptions o = options;
    o.seed = seed;
    o.max_error = general.camera.CamFromImgThreshold(options.max_error);
    return EstimateEssentialMatrix(x1, x2, o).num_inliers;
  }, &e_inliers);

  const Timing h_time = Time([&](int seed) {
    RansacOptions o = options;
    o.seed = seed;
    return EstimateHomographyMatrix(planar.points1, planar.points2, o).num_inliers;
  }, &h_inliers);

  // 2D-3D matches: the first view's pixels of the general scene's points,
  // half of them replaced by random pixels.
  const TwoViewMatches scene = Matches(testing::TwoViewScene::kGeneral, 1000);
  std::vector<Eigen::Vector2d> pixels = scene.points1;
  std::mt19937 rng(2);
  std::uniform_real_distribution<double> unit(0, 1);
  for (std::size_t i = 0; i < pixels.size(); i += 2) {
    pixels[i] = Eigen::Vector2d(unit(rng) * scene.camera.width, unit(rng) * scene.camera.height);
  }
  const Timing pose_time = Time([&](int seed) {
    AbsolutePoseOptions o;
    o.ransac.seed = seed;
    return EstimateAbsolutePose(scene.camera, pixels, scene.points3D, o).num_inliers;
  }, &pose_inliers);

  std::printf("F RANSAC (7-pt, LO 8-pt), 2000 matches, 50%% outliers: %.2f ms wall, %.2f ms CPU, "
              "%d inliers (%d true)\n", f_time.wall_ms, f_time.cpu_ms, f_inliers, general.NumInliers());
  std::printf("E RANSAC (5-pt, LO 5-pt, LM), 2000 matches, 50%% outliers: %.2f ms wall, %.2f ms CPU, "
              "%d inliers (%d true)\n", e_time.wall_ms, e_time.cpu_ms, e_inliers, general.NumInliers());
  std::printf("H RANSAC (4-pt DLT, LO DLT), 2000 matches, 50%% outliers: %.2f ms wall, %.2f ms CPU, "
              "%d inliers (%d true)\n", h_time.wall_ms, h_time.cpu_ms, h_inliers, planar.NumInliers());
  std::printf("Absolute pose RANSAC (P3P, LO EPnP + LM), 1000 matches, 50%% outliers: %.2f ms wall, "
              "%.2f ms CPU, %d inliers (500 true)\n", pose_time.wall_ms, pose_time.cpu_ms, pose_inliers);
  std::printf("{\"bench\":\"geometry\",\"runs\":%d,\"target_ms\":10,"
              "\"f_ransac_ms\":%.3f,\"e_ransac_ms\":%.3f,\"h_ransac_ms\":%.3f,\"abs_pose_ransac_ms\":%.3f,"
              "\"f_ransac_cpu_ms\":%.3f,\"e_ransac_cpu_ms\":%.3f,\"h_ransac_cpu_ms\":%.3f,"
              "\"abs_pose_ransac_cpu_ms\":%.3f}\n",
              kRuns, f_time.wall_ms, e_time.wall_ms, h_time.wall_ms, pose_time.wall_ms, f_time.cpu_ms,
              e_time.cpu_ms, h_time.cpu_ms, pose_time.cpu_ms);
  return 0;
}
