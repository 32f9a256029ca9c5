#include "lsm/densify.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <random>
#include <string>
#include <vector>

#include <catch2/catch.hpp>

#include "io/synthetic/synthetic_scene.h"
#include "tests/testing/synthetic.h"

namespace flysfm {
namespace {

// A camera at `center` looking along +z, turned by small angles (radians)
// about its x and y axes.
Rigid3d LookingForward(const Eigen::Vector3d& center, double tilt_x,
                       double tilt_y) {
  const Eigen::Matrix3d rotation =
      (Eigen::AngleAxisd(tilt_x, Eigen::Vector3d::UnitX()) *
       Eigen::AngleAxisd(tilt_y, Eigen::Vector3d::UnitY()))
          .toRotationMatrix();
  return Rigid3d(rotation, -rotation * center);
}

LsmView MakeView(const TexturedScene& scene, const Camera& camera,
                 const Rigid3d& cam_from_world, int levels) {
  LsmView view;
  view.camera = camera;
  view.cam_from_world = cam_from_world;
  view.pyramid =
      BuildLsmPyramid(Render(scene, camera, cam_from_world).image, levels);
  return view;
}

struct Scenario {
  TexturedScene scene;
  Camera camera;
  std::vector<LsmView> references;
  Rigid3d true_pose;
  std::vector<DensifyCandidate> candidates;
};

// Three reference views and a new one, the candidates every point of the
// scene seen by a reference, observed at its exact projection. Without
// `render`, the views have their poses but no pixels (a test of geometry
// alone: rendering takes most of a minute under a sanitizer).
Scenario MakeScenario(int levels, bool render = true) {
  Scenario scenario;
  scenario.scene = MakeFacetScene(3);
  // OpenCV pixel convention: the principal point of a centred lens.
  scenario.camera = Camera::FromString("PINHOLE 500,500,319.5,239.5", 640, 480);
  const Rigid3d reference_poses[] = {
      LookingForward({-0.8, 0.1, -5.0}, 0.01, 0.03),
      LookingForward({-0.3, -0.1, -5.2}, -0.01, 0.01),
      LookingForward({0.3, 0.15, -4.9}, 0.02, -0.02)};
  for (const Rigid3d& pose : reference_poses) {
    if (render) {
      scenario.references.push_back(MakeView(scenario.scene, scenario.camera, pose, levels));
    } else {
      LsmView view;
      view.camera = scenario.camera;
      view.cam_from_world = pose;
      scenario.references.push_back(view);
    }
  }
  scenario.true_pose = LookingForward({0.7, 0.0, -5.1}, -0.02, -0.05);

  std::mt19937 rng(17);
  for (const Eigen::Vector3d& point :
       SamplePointsOnFacets(scenario.scene, 1500, rng)) {
    DensifyCandidate candidate;
    candidate.xyz = point;
    for (int v = 0; v < 3; ++v) {
      const LsmView& reference = scenario.references[v];
      if (!IsVisible(scenario.scene, scenario.camera, reference.cam_from_world,
                     point)) {
        continue;
      }
      candidate.observations.push_back(
          {v, scenario.camera.ImgFromCam(reference.cam_from_world * point)});
    }
    if (!candidate.observations.empty()) {
      scenario.candidates.push_back(candidate);
    }
  }
  return scenario;
}

// Ground truth of one candidate in the new image, from the exact pose and
// the rendered depth map.
enum class Truth {
  kOutside,        // projects outside the image
  kDeeplyHidden,   // behind a nearer facet, 3 px or more from its edge
  kHiddenAtEdge,   // behind a nearer facet, within 3 px of its edge
  kNoRoom,         // visible, but the 15x15 window does not fit the image
  kSingleSurface,  // visible, its window on one surface
  kAtDepthEdge,    // visible, its window across a depth discontinuity
};

Truth Classify(const Scenario& scenario, const RenderedView& rendered,
               const Eigen::Vector3d& point, int window_size) {
  const Camera& camera = scenario.camera;
  const Eigen::Vector3d in_cam = scenario.true_pose * point;
  const Eigen::Vector2d projection = camera.ImgFromCam(in_cam);
  if (in_cam.z() <= 0 || projection.x() < -0.5 || projection.y() < -0.5 ||
      projection.x() > camera.width - 0.5 ||
      projection.y() > camera.height - 0.5) {
    return Truth::kOutside;
  }
  const int col = static_cast<int>(std::lround(projection.x()));
  const int row = static_cast<int>(std::lround(projection.y()));
  const auto depth_at = [&](int r, int c) {
    return rendered.depth.at<float>(std::clamp(r, 0, camera.height - 1),
                                    std::clamp(c, 0, camera.width - 1));
  };
  if (!IsVisible(scenario.scene, camera, scenario.true_pose, point)) {
    for (int dr = -3; dr <= 3; ++dr) {
      for (int dc = -3; dc <= 3; ++dc) {
        if (depth_at(row + dr, col + dc) >= 0.999 * in_cam.z()) {
          return Truth::kHiddenAtEdge;
        }
      }
    }
    return Truth::kDeeplyHidden;
  }
  // The window plus the spline's margin.
  const int reach = window_size / 2 + 3;
  if (col < reach || row < reach || col > camera.width - 1 - reach ||
      row > camera.height - 1 - reach) {
    return Truth::kNoRoom;
  }
  // A facet changes depth by far less than 5 % across 15 pixels; a depth
  // edge between facets by more.
  const int radius = window_size / 2;
  for (int dr = -radius; dr <= radius; ++dr) {
    for (int dc = -radius; dc <= radius; ++dc) {
      if (std::abs(depth_at(row + dr, col + dc) / in_cam.z() - 1.0) > 0.05) {
        return Truth::kAtDepthEdge;
      }
    }
  }
  return Truth::kSingleSurface;
}

TEST_CASE(
    "Densify adds visible points from a perturbed pose, not hidden ones") {
  const DensifyOptions options;
  const Scenario scenario = MakeScenario(options.num_pyramid_levels);

  const Rigid3d& truth = scenario.true_pose;
  const RenderedView rendered = Render(scenario.scene, scenario.camera, truth);
  // Three random perturbations, each of exactly 1 deg and 2 cm.
  for (const std::uint32_t seed : {5u, 6u, 7u}) {
    INFO("perturbation seed " << seed);
    // The initial pose: 1 deg and 2 cm off the truth.
    std::mt19937 rng(seed);
    const Eigen::Vector3d center =
        ProjectionCenter(truth) + 0.02 * testing::RandomUnitVector(rng);
    const Eigen::Matrix3d rotation =
        (testing::RandomRotationOfAngle(rng, 1.0) * truth.rotation)
            .toRotationMatrix();
    const Rigid3d initial(rotation, -rotation * center);
    REQUIRE(RotationDifferenceDeg(initial, truth) == Approx(1.0).epsilon(1e-6));

    LsmView image;
    image.camera = scenario.camera;
    image.cam_from_world = initial;
    image.pyramid = BuildLsmPyramid(rendered.image, options.num_pyramid_levels);
    const DensifyResult result =
        Densify(image, scenario.references, scenario.candidates, options);
    CHECK(result.num_candidates ==
          static_cast<int>(scenario.candidates.size()));

    std::vector<int> added(scenario.candidates.size(), -1);
    for (size_t m = 0; m < result.matches.size(); ++m) {
      added[result.matches[m].candidate] = static_cast<int>(m);
    }
    constexpr int kNumTruths = 6;
    int total[kNumTruths] = {};
    int kept[kNumTruths] = {};
    // Position errors of the added visible points, by class.
    std::vector<double> errors[kNumTruths];
    for (size_t c = 0; c < scenario.candidates.size(); ++c) {
      const Eigen::Vector3d& point = scenario.candidates[c].xyz;
      const Truth truth_class =
          Classify(scenario, rendered, point, options.lsm.window_size);
      ++total[static_cast<int>(truth_class)];
      if (added[c] < 0) continue;
      ++kept[static_cast<int>(truth_class)];
      errors[static_cast<int>(truth_class)].push_back(
          (result.matches[added[c]].point2D -
           scenario.camera.ImgFromCam(truth * point))
              .norm());
    }
    const auto figure = [&](Truth t) {
      return std::to_string(kept[static_cast<int>(t)]) + "/" +
             std::to_string(total[static_cast<int>(t)]);
    };
    const int single = static_cast<int>(Truth::kSingleSurface);
    const int edge = static_cast<int>(Truth::kAtDepthEdge);
    const int no_room = static_cast<int>(Truth::kNoRoom);
    const int visible = total[single] + total[edge] + total[no_room];
    const int visible_added = kept[single] + kept[edge] + kept[no_room];
    std::printf(
        "densify %u: added of visible %d/%d (single surface %s, at depth edges "
        "%s, "
        "no room %s); hidden %s deep, %s at edges; outside %s\n",
        seed, visible_added, visible, figure(Truth::kSingleSurface).c_str(),
        figure(Truth::kAtDepthEdge).c_str(), figure(Truth::kNoRoom).c_str(),
        figure(Truth::kDeeplyHidden).c_str(),
        figure(Truth::kHiddenAtEdge).c_str(), figure(Truth::kOutside).c_str());
    std::string outcomes;
    for (int s = 0; s < kNumLsmStatus; ++s) {
      outcomes += std::string(" ") + LsmStatusName(static_cast<LsmStatus>(s)) +
                  "=" + std::to_string(result.lsm_counts.counts[s]);
    }
    std::printf(
        "densify %u: LSM outcomes%s; imprecise %d, no reference %d, displaced "
        "%d\n",
        seed, outcomes.c_str(), result.num_imprecise, result.num_no_reference,
        result.num_displaced);
    std::vector<double> all_errors;
    for (const int t : {single, edge, no_room}) {
      std::vector<double>& e = errors[t];
      all_errors.insert(all_errors.end(), e.begin(), e.end());
      if (e.empty()) continue;
      std::sort(e.begin(), e.end());
      std::printf(
          "densify %u: position error (%s) median %.4f px, 90th percentile "
          "%.4f "
          "px, %d beyond 0.5 px\n",
          seed,
          t == single ? "single surface"
          : t == edge ? "depth edges"
                      : "no room",
          e[e.size() / 2], e[e.size() * 9 / 10],
          static_cast<int>(e.end() -
                           std::upper_bound(e.begin(), e.end(), 0.5)));
    }
    REQUIRE(total[single] >= 300);
    REQUIRE(total[edge] >= 50);
    REQUIRE(total[static_cast<int>(Truth::kDeeplyHidden)] >= 50);
    REQUIRE(total[static_cast<int>(Truth::kOutside)] >= 50);
    // The criteria: >= 90 % of the visible points added, median
    // position error below 0.1 px.
    CHECK(visible_added >= 0.9 * visible);
    REQUIRE(!all_errors.empty());
    std::nth_element(all_errors.begin(),
                     all_errors.begin() + all_errors.size() / 2,
                     all_errors.end());
    std::printf("densify %u: median position error %.4f px\n", seed,
                all_errors[all_errors.size() / 2]);
    CHECK(all_errors[all_errors.size() / 2] < 0.1);
    CHECK(kept[static_cast<int>(Truth::kDeeplyHidden)] == 0);
    CHECK(kept[static_cast<int>(Truth::kOutside)] == 0);
  }
}

TEST_CASE("The predicted affine map matches the rendered geometry") {
  const Scenario scenario = MakeScenario(1, /*render=*/false);
  LsmView image;
  image.camera = scenario.camera;
  image.cam_from_world = scenario.true_pose;
  // On a facet fronto-parallel to the reference camera's image plane up to
  // its small tilt, the plane-induced map is the true one: check it against
  // finite differences of the exact projections of neighbouring points on
  // the back wall.
  const LsmView& reference = scenario.references[1];
  const Eigen::Vector3d point(-3.0, 2.5, 2.0);  // on the back wall, unoccluded
  const Eigen::Vector2d reference_point =
      scenario.camera.ImgFromCam(reference.cam_from_world * point);
  const Eigen::Matrix2d predicted =
      PredictAffine(reference, reference_point, point, image);
  CHECK(predicted.determinant() > 0.0);
  // Exact map for the wall plane z = 2: transfer along the wall.
  const auto wall_transfer = [&](const Eigen::Vector2d& pixel) {
    const Eigen::Vector3d ray_in_cam =
        scenario.camera.CamFromImg(pixel).homogeneous();
    const Eigen::Vector3d center = ProjectionCenter(reference.cam_from_world);
    const Eigen::Vector3d direction =
        reference.cam_from_world.rotation.conjugate() * ray_in_cam;
    const Eigen::Vector3d on_wall =
        center + (2.0 - center.z()) / direction.z() * direction;
    return scenario.camera.ImgFromCam(scenario.true_pose * on_wall);
  };
  Eigen::Matrix2d exact;
  for (int axis = 0; axis < 2; ++axis) {
    const Eigen::Vector2d step = Eigen::Vector2d::Unit(axis);
    exact.col(axis) = 0.5 * (wall_transfer(reference_point + step) -
                             wall_transfer(reference_point - step));
  }
  // The reference camera is tilted by about 1 deg against the wall: the
  // fronto-parallel assumption errs by about that much in the map.
  CHECK((predicted - exact).norm() < 0.03);
}

TEST_CASE("Densify rejects bad options, pyramids and observations") {
  DensifyOptions options;
  CHECK(options.Check());
  for (const auto& spoil : std::vector<void (*)(DensifyOptions*)>{
           [](DensifyOptions* o) { o->max_references_per_point = 0; },
           [](DensifyOptions* o) { o->window_shift_px = -1.0; },
           [](DensifyOptions* o) { o->max_relative_sigma0 = 0.0; }}) {
    DensifyOptions spoilt;
    spoil(&spoilt);
    CHECK_FALSE(spoilt.Check());
  }
  options.num_pyramid_levels = 0;
  CHECK_FALSE(options.Check());
  LsmView image;
  image.camera = Camera::FromString("PINHOLE 500,500,319.5,239.5", 640, 480);
  image.pyramid = BuildLsmPyramid(cv::Mat(480, 640, CV_8U, cv::Scalar(0)), 1);
  CHECK_THROWS_AS(Densify(image, {}, {}, options), std::invalid_argument);
  // Three levels needed by default.
  CHECK_THROWS_AS(Densify(image, {}, {}), std::invalid_argument);
  image.pyramid = BuildLsmPyramid(cv::Mat(480, 640, CV_8U, cv::Scalar(0)), 3);
  DensifyCandidate candidate;
  candidate.xyz = Eigen::Vector3d(0, 0, 5);
  candidate.observations.push_back({2, Eigen::Vector2d(100, 100)});
  CHECK_THROWS_AS(Densify(image, {}, {candidate}), std::invalid_argument);
  // A point behind the camera is counted, not matched.
  candidate.observations.clear();
  candidate.xyz = Eigen::Vector3d(0, 0, -5);
  const DensifyResult behind = Densify(image, {}, {candidate});
  CHECK(behind.num_behind == 1);
  CHECK(behind.matches.empty());
}

}  // namespace
}  // namespace flysfm
