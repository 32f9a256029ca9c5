#pragma once

// Bundle problems from the synthetic scenes of tests/testing, shared by the
// bundle and scene-bundle tests and bench/bench_bundle.cc.

#include <cmath>
#include <random>

#include "bundle/bundle_problem.h"
#include "tests/testing/synthetic.h"

namespace flysfm::testing {

// All images of the scene (one camera, weight 1, none constant), its points
// and its observations, at the exact ground truth.
inline BundleProblem BundleProblemFromScene(const SyntheticScene& scene) {
  BundleProblem problem;
  problem.cameras.push_back(scene.camera);
  for (const Rigid3d& pose : scene.cams_from_world) {
    BundleImage image;
    image.cam_from_world = pose;
    problem.images.push_back(image);
  }
  problem.points = scene.points;
  for (const SyntheticObservation& obs : scene.observations) {
    problem.observations.push_back({obs.image, obs.point, obs.pixel});
  }
  return problem;
}

// Rotates a pose by `angle_deg` about a random axis and moves its camera
// centre by `shift` in a random direction.
inline void PerturbPose(std::mt19937& rng, double angle_deg, double shift,
                        Rigid3d* cam_from_world) {
  const Eigen::Vector3d center = ProjectionCenter(*cam_from_world) +
                                 shift * RandomUnitVector(rng);
  cam_from_world->rotation =
      (RandomRotationOfAngle(rng, angle_deg) * cam_from_world->rotation).normalized();
  cam_from_world->translation = -(cam_from_world->rotation * center);
}

// Root mean square of the reprojection residuals per image axis, in pixels:
// for Gaussian noise of standard deviation s per axis it tends to s.
inline double RmsReprojectionError(const BundleProblem& problem) {
  double sum = 0;
  for (const double e : ReprojectionErrors(problem)) sum += e * e;
  return std::sqrt(sum / (2.0 * problem.observations.size()));
}

}  // namespace flysfm::testing
