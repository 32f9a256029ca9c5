#pragma once

// Matched keypoints between two synthetic views with exact ground truth
// (poses, 3D points, which matches are outliers), for the two-view solvers,
// RANSAC, GRIC and their benchmark.

#include <cstdint>
#include <vector>

#include <Eigen/Core>

#include "geometry/camera.h"
#include "geometry/rigid3d.h"

namespace flysfm::testing {

enum class TwoViewScene {
  kGeneral,       // points in a 3D box, cameras with a baseline
  kPlanar,        // points on one plane, cameras with a baseline
  kPureRotation,  // both cameras at the same centre
};

struct TwoViewMatchesOptions {
  TwoViewScene scene = TwoViewScene::kGeneral;
  int num_matches = 500;
  // Fraction of matches whose second point is replaced by a uniformly random
  // pixel of the image.
  double outlier_ratio = 0.0;
  // Gaussian noise (standard deviation, pixels) on both points of a match.
  double noise_px = 0.0;
  // The cameras sit on a circle of this radius around a scene of half-size
  // 1, this many degrees apart, looking at its centre.
  double camera_distance = 3.0;
  double arc_deg = 20.0;
  Camera camera = Camera::FromFocal(CameraModelId::kPinhole, 500, 640, 480);
  std::uint32_t seed = 0;
};

struct TwoViewMatches {
  Camera camera;
  Rigid3d cam1_from_world;
  Rigid3d cam2_from_world;
  std::vector<Eigen::Vector2d> points1;  // pixels, with noise
  std::vector<Eigen::Vector2d> points2;
  std::vector<char> is_inlier;
  std::vector<Eigen::Vector3d> points3D;  // world point of each match

  Rigid3d Cam2FromCam1() const;
  int NumInliers() const;
};

TwoViewMatches MakeTwoViewMatches(const TwoViewMatchesOptions& options);

// Fraction of matches whose estimated flag equals the true one.
double InlierClassificationRate(const std::vector<char>& estimated,
                                const std::vector<char>& truth);

}  // namespace flysfm::testing
