#pragma once

// The bundle module's own description of an adjustment problem: plain arrays
// indexed from 0, so that it is built and tested without the engine's scene.
// Solving refines the problem in place.

#include <vector>

#include <Eigen/Core>

#include "geometry/camera.h"
#include "geometry/rigid3d.h"

namespace flysfm {

struct BundleImage {
  int camera = 0;  // index into BundleProblem::cameras
  Rigid3d cam_from_world;
  // Hierarchical weight p of the paper's Eq. 4, >= 1. An image with p > 1 is
  // anchored to its pose before the solve by a prior whose information is
  // (p - 1) times its own reprojection information (docs/bundle.md), so it
  // moves about 1/p as much as an unweighted image would. p = 1 adds nothing.
  double weight = 1.0;
  // The pose is not refined (p = infinity in Eq. 4; images outside the local
  // block that observe its points).
  bool constant_pose = false;
  // The camera's motion while its rows are read out, in its own frame per
  // second (Camera::InCamAtRow): the pose is the middle row's. Zero for a
  // still camera (every photo).
  Eigen::Vector3d angular_velocity = Eigen::Vector3d::Zero();
  Eigen::Vector3d linear_velocity = Eigen::Vector3d::Zero();

  bool IsMoving() const {
    return !angular_velocity.isZero(0) || !linear_velocity.isZero(0);
  }
};

struct BundleObservation {
  int image = 0;
  int point = 0;
  Eigen::Vector2d pixel = Eigen::Vector2d::Zero();
};

struct BundleProblem {
  std::vector<Camera> cameras;
  std::vector<BundleImage> images;
  std::vector<Eigen::Vector3d> points;
  std::vector<BundleObservation> observations;

  // Indices in range, cameras valid, weights finite and >= 1.
  bool Check() const;
};

// Reprojection error in pixels of one observation; a point behind its camera
// counts as infinitely far off.
double ReprojectionError(const BundleProblem& problem,
                         const BundleObservation& observation);
// The same for every observation, in observation order.
std::vector<double> ReprojectionErrors(const BundleProblem& problem);

}  // namespace flysfm
