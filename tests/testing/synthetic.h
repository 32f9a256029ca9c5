#pragma once

// Synthetic scenes with exact ground truth, for tests and benchmarks of every
// module. Deterministic for a given seed.

#include <cstdint>
#include <random>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "geometry/camera.h"
#include "geometry/rigid3d.h"

namespace flysfm::testing {

// A rotation drawn uniformly from SO(3).
Eigen::Quaterniond RandomRotation(std::mt19937& rng);
// A rotation about a uniformly random axis by `angle_deg`.
Eigen::Quaterniond RandomRotationOfAngle(std::mt19937& rng, double angle_deg);
Eigen::Vector3d RandomUnitVector(std::mt19937& rng);

struct SyntheticSceneOptions {
  int num_images = 10;
  int num_points = 500;
  // Observation noise, standard deviation in pixels.
  double noise_px = 0.0;
  // Points are drawn in a box of this half-size around the origin; cameras sit
  // on a circle of radius `camera_distance` around it, looking at the origin,
  // each with a random tilt of up to `max_tilt_deg`.
  double scene_half_size = 1.0;
  double camera_distance = 5.0;
  // Angular spread of the cameras around the circle, in degrees.
  double arc_deg = 60.0;
  double max_tilt_deg = 5.0;
  // All points on the plane z = 0 (a degenerate scene for F, ideal for H).
  bool planar = false;
  Camera camera = Camera::FromFocal(CameraModelId::kPinhole, 500, 640, 480);
  std::uint32_t seed = 0;
};

struct SyntheticObservation {
  int image = 0;
  int point = 0;
  Eigen::Vector2d pixel = Eigen::Vector2d::Zero();  // with noise
};

struct SyntheticScene {
  Camera camera;
  std::vector<Rigid3d> cams_from_world;
  std::vector<Eigen::Vector3d> points;
  // Every point in front of a camera and inside its image.
  std::vector<SyntheticObservation> observations;

  // Observations of one image, in point order.
  std::vector<SyntheticObservation> ObservationsOf(int image) const;
};

SyntheticScene MakeSyntheticScene(const SyntheticSceneOptions& options);

}  // namespace flysfm::testing
