#include "bench/photo_session.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <random>
#include <sstream>
#include <thread>

#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "io/synthetic/procedural_texture.h"
#include "io/synthetic/synthetic_scene.h"

namespace flysfm {
namespace {

// The building's footprint, x in [-kHalfX, kHalfX], y in [-kHalfY, kHalfY]
// (world z up, ground at z = 0): 16 m x 12 m, 8 m high.
constexpr double kHalfX = 8.0;
constexpr double kHalfY = 6.0;
constexpr double kHeight = 8.0;
// Wall texels of 4 mm: a pixel of a 6 MP photo with a 30 mm-equivalent lens
// (focal 2500 px) covers 3.2-6 mm at 8-15 m, so the walls are as sharp as the
// sensor there. The 28 M wall texels take 112 MB as floats. The ground is
// seen at grazing angles and needs far fewer (2.5 cm).
constexpr double kWallTexelsPerMetre = 250.0;
constexpr double kGroundTexelsPerMetre = 40.0;
constexpr double kGroundHalfSize = 36.0;
// Bumped whenever the scene or the path changes, so that a folder of
// renders is never reused stale.
constexpr int kSceneVersion = 1;
// Bumped whenever MakeRingShots changes.
constexpr int kRingPlanVersion = 1;

// Every facet has its own texture (seeded by its index): no two places look
// alike, as on a real facade with its dirt and weathering.
TexturedScene MakeBuilding(std::uint32_t seed) {
  TexturedScene scene;
  std::uint32_t texture_seed = seed * 7919u;
  for (const BuildingFacet& geometry : BuildingFacets()) {
    TexturedFacet facet;
    facet.origin = geometry.origin;
    facet.axis_u = geometry.axis_u;
    facet.axis_v = geometry.axis_v;
    const int cols = int(std::ceil(geometry.axis_u.norm() * geometry.texels_per_metre));
    const int rows = int(std::ceil(geometry.axis_v.norm() * geometry.texels_per_metre));
    cv::Mat texture;
    MakeTexture(cols, rows, ++texture_seed).convertTo(texture, CV_32F);
    // Less than a texel of blur: band-limited enough that one sample per
    // pixel does not alias where a pixel covers a texel or two.
    cv::GaussianBlur(texture, facet.texture, cv::Size(), 0.8);
    scene.facets.push_back(std::move(facet));
  }
  return scene;
}

// One loop around the building: the footprint offset by `distance` metres
// (straight along the walls, quarter circles round the corners) at `height`.
struct Loop {
  double height;
  double distance;
};

// The footprint point `s` metres along the loop at `distance` (modulo its
// length) and the outward direction from it to the loop, on the ground.
void PointOnLoop(double s, double distance, Eigen::Vector2d* nearest,
                 Eigen::Vector2d* outward) {
  const Eigen::Vector2d corners[4] = {
      {-kHalfX, -kHalfY}, {kHalfX, -kHalfY}, {kHalfX, kHalfY}, {-kHalfX, kHalfY}};
  const Eigen::Vector2d normals[4] = {{0, -1}, {1, 0}, {0, 1}, {-1, 0}};
  const double arc = 0.5 * M_PI * distance;
  const double perimeter = 4 * (kHalfX + kHalfY) + 4 * arc;
  s = std::fmod(s, perimeter);
  if (s < 0) s += perimeter;
  for (int side = 0; side < 4; ++side) {
    const Eigen::Vector2d& from = corners[side];
    const Eigen::Vector2d& to = corners[(side + 1) % 4];
    const double length = (to - from).norm();
    if (s <= length) {
      *nearest = from + s / length * (to - from);
      *outward = normals[side];
      return;
    }
    s -= length;
    if (s <= arc || side == 3) {
      // Round the corner: the outward normal turns counter-clockwise.
      const double angle = std::min(s, arc) / distance;
      const Eigen::Vector2d& n = normals[side];
      *nearest = to;
      *outward = Eigen::Vector2d(std::cos(angle) * n.x() - std::sin(angle) * n.y(),
                                 std::sin(angle) * n.x() + std::cos(angle) * n.y());
      return;
    }
    s -= arc;
  }
}

double LoopLength(double distance) { return 4 * (kHalfX + kHalfY) + 2 * M_PI * distance; }

}  // namespace

std::vector<BuildingFacet> BuildingFacets() {
  std::vector<BuildingFacet> facets;
  const auto add = [&](const Eigen::Vector3d& origin, const Eigen::Vector3d& u,
                       const Eigen::Vector3d& v, double texels_per_metre) {
    facets.push_back({origin, u, v, texels_per_metre});
  };
  const Eigen::Vector3d x = Eigen::Vector3d::UnitX();
  const Eigen::Vector3d y = Eigen::Vector3d::UnitY();
  const Eigen::Vector3d z = Eigen::Vector3d::UnitZ();
  const double w = kWallTexelsPerMetre;
  // The four walls, counter-clockwise from the south one (y = -kHalfY).
  add({-kHalfX, -kHalfY, 0}, 2 * kHalfX * x, kHeight * z, w);
  add({kHalfX, -kHalfY, 0}, 2 * kHalfY * y, kHeight * z, w);
  add({kHalfX, kHalfY, 0}, -2 * kHalfX * x, kHeight * z, w);
  add({-kHalfX, kHalfY, 0}, -2 * kHalfY * y, kHeight * z, w);
  // Two bays (front, two sides, roof) give depth and occlusions: one on the
  // south wall, 4 m wide, 1.5 m out, 5 m high; one on the east wall.
  const auto bay = [&](const Eigen::Vector3d& corner, const Eigen::Vector3d& along,
                       const Eigen::Vector3d& out, double height) {
    add(corner + out, along, height * z, w);          // front
    add(corner, out, height * z, w);                  // side
    add(corner + along, out, height * z, w);          // other side
    add(corner + height * z, along, out, w);          // roof
  };
  bay({-3.0, -kHalfY, 0}, 4.0 * x, -1.5 * y, 5.0);
  bay({kHalfX, -1.0, 0}, 3.0 * y, 1.2 * x, 3.5);
  // The ground.
  add({-kGroundHalfSize, -kGroundHalfSize, 0}, 2 * kGroundHalfSize * x,
      2 * kGroundHalfSize * y, kGroundTexelsPerMetre);
  return facets;
}

std::vector<Shot> MakePhotoSession(int num_photos, std::uint32_t seed) {
  const std::vector<Loop> loops = {{1.6, 10.0}, {1.6, 16.0}, {4.5, 12.0}, {1.6, 10.0},
                                   {3.0, 14.0}};
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> step(1.0, 3.0);
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  std::vector<Shot> shots;
  for (int loop_index = 0; int(shots.size()) < num_photos; ++loop_index) {
    const Loop& loop = loops[loop_index % loops.size()];
    const bool wandering = loop_index % loops.size() == 4;
    // Each loop starts somewhere else along the south wall.
    const double start = 4.0 * unit(rng);
    for (double s = 0; s < LoopLength(loop.distance) && int(shots.size()) < num_photos;
         s += step(rng)) {
      const double distance =
          wandering ? 14.0 + 6.0 * std::sin(0.15 * s) + unit(rng) : loop.distance + unit(rng);
      Eigen::Vector2d nearest, outward;
      PointOnLoop(start + s, loop.distance, &nearest, &outward);
      const Eigen::Vector2d ground = nearest + distance * outward;
      const Eigen::Vector3d center(ground.x(), ground.y(), loop.height + 0.1 * unit(rng));
      // Aim at the nearest facade point at 3.5 m, turned by up to 10 deg of
      // yaw and 4 deg of pitch; up to 2 deg of roll.
      const Eigen::Vector3d target(nearest.x(), nearest.y(), 3.5);
      Eigen::Vector3d forward = (target - center).normalized();
      const Eigen::Vector3d up = Eigen::Vector3d::UnitZ();
      forward = Eigen::AngleAxisd(10.0 * M_PI / 180 * unit(rng), up) * forward;
      Eigen::Vector3d right = forward.cross(up).normalized();
      forward = Eigen::AngleAxisd(4.0 * M_PI / 180 * unit(rng), right) * forward;
      right = forward.cross(up).normalized();
      right = Eigen::AngleAxisd(2.0 * M_PI / 180 * unit(rng), forward) * right;
      // Camera axes: x right, y down, z forward.
      Eigen::Matrix3d world_from_cam;
      world_from_cam << right, forward.cross(right), forward;
      Shot shot;
      char name[32];
      std::snprintf(name, sizeof(name), "photo_%04d.jpg", int(shots.size()));
      shot.name = name;
      shot.cam_from_world = Rigid3d(Eigen::Matrix3d(world_from_cam.transpose()),
                                    -(world_from_cam.transpose() * center));
      shot.distance_to_building = (ground - nearest).norm();
      shots.push_back(shot);
    }
  }
  return shots;
}

std::vector<Shot> MakeRingShots(const std::vector<RingStop>& stops, std::uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  const Eigen::Vector3d up = Eigen::Vector3d::UnitZ();
  const Eigen::Vector3d target(0, 0, 3.5);
  std::vector<Shot> shots;
  for (const RingStop& stop : stops) {
    const double angle = stop.angle_deg * M_PI / 180;
    const double radius = stop.radius_m + 0.3 * unit(rng);
    const Eigen::Vector3d center(radius * std::cos(angle), radius * std::sin(angle),
                                 stop.height_m + 0.1 * unit(rng));
    Eigen::Vector3d forward = (target - center).normalized();
    forward = Eigen::AngleAxisd(5.0 * M_PI / 180 * unit(rng), up) * forward;
    Eigen::Vector3d right = forward.cross(up).normalized();
    forward = Eigen::AngleAxisd(3.0 * M_PI / 180 * unit(rng), right) * forward;
    right = forward.cross(up).normalized();
    right = Eigen::AngleAxisd(2.0 * M_PI / 180 * unit(rng), forward) * right;
    // Camera axes: x right, y down, z forward.
    Eigen::Matrix3d world_from_cam;
    world_from_cam << right, forward.cross(right), forward;
    Shot shot;
    shot.name = stop.name;
    shot.cam_from_world = Rigid3d(Eigen::Matrix3d(world_from_cam.transpose()),
                                  -(world_from_cam.transpose() * center));
    const Eigen::Vector2d outside(std::max(0.0, std::abs(center.x()) - kHalfX),
                                  std::max(0.0, std::abs(center.y()) - kHalfY));
    shot.distance_to_building = outside.norm();
    shots.push_back(shot);
  }
  return shots;
}

std::vector<double> RenderPhotoSession(const std::vector<Shot>& shots, const Camera& camera,
                                  std::uint32_t seed, int supersampling,
                                  const std::filesystem::path& dir, int num_threads) {
  std::vector<int> missing;
  for (int i = 0; i < int(shots.size()); ++i) {
    if (!std::filesystem::exists(dir / shots[i].name)) missing.push_back(i);
  }
  if (missing.empty()) return {};
  const auto start = std::chrono::steady_clock::now();
  const TexturedScene scene = MakeBuilding(seed);
  std::size_t texels = 0;
  for (const TexturedFacet& facet : scene.facets) texels += facet.texture.total();
  // Progress, on stderr: a benchmark's stdout is its table.
  std::fprintf(stderr, "scene: %zu facets, %.0f MB of textures, made in %.1f s\n",
               scene.facets.size(), texels * sizeof(float) / 1048576.0,
               std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
  std::vector<double> times(missing.size());
  const auto work = [&](int thread) {
    for (std::size_t k = thread; k < missing.size(); k += num_threads) {
      const Shot& shot = shots[missing[k]];
      const auto begin = std::chrono::steady_clock::now();
      const RenderedView view = Render(scene, camera, shot.cam_from_world, supersampling);
      times[k] = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - begin).count();
      // A colour photo (slightly warm), so that decoding does a camera
      // JPEG's chroma work.
      cv::Mat bgr;
      cv::cvtColor(view.image, bgr, cv::COLOR_GRAY2BGR);
      cv::multiply(bgr, cv::Scalar(0.9, 1.0, 1.05), bgr);
      const std::string tmp = (dir / (shot.name + ".tmp.jpg")).string();
      cv::imwrite(tmp, bgr, {cv::IMWRITE_JPEG_QUALITY, 92});
      std::filesystem::rename(tmp, dir / shot.name);
    }
  };
  std::vector<std::thread> threads;
  for (int t = 0; t < num_threads; ++t) threads.emplace_back(work, t);
  for (std::thread& thread : threads) thread.join();
  return times;
}

std::string PhotoSessionCamera(int width) {
  const double focal = width * 30.0 / 36.0;
  std::ostringstream text;
  text << "PINHOLE " << focal << "," << focal << "," << 0.5 * (width - 1) << ","
       << 0.5 * (width * 2 / 3 - 1);
  return text.str();
}

void PrepareRenderFolder(const std::filesystem::path& dir, std::uint32_t seed,
                         const Camera& camera, int supersampling, const std::string& plan) {
  nlohmann::json manifest = {{"scene_version", kSceneVersion},
                             {"seed", seed},
                             {"width", camera.width},
                             {"height", camera.height},
                             {"supersampling", supersampling}};
  // Absent for bench_photos' path, so that folders rendered before the
  // ring plans existed stay valid.
  if (!plan.empty()) {
    manifest["plan"] = plan;
    manifest["ring_plan_version"] = kRingPlanVersion;
  }
  std::filesystem::create_directories(dir);
  nlohmann::json existing;
  std::ifstream in(dir / "manifest.json");
  if (in) in >> existing;
  if (existing == manifest) return;
  for (const auto& entry : std::filesystem::directory_iterator(dir)) {
    if (entry.path().extension() == ".jpg") std::filesystem::remove(entry.path());
  }
  std::ofstream(dir / "manifest.json") << manifest.dump() << "\n";
}

}  // namespace flysfm
