#include "bundle/bundle_problem.h"

#include <cmath>
#include <limits>

namespace flysfm {

bool BundleProblem::Check() const {
  for (const Camera& camera : cameras) {
    if (!camera.IsValid() || !std::isfinite(camera.readout_time)) return false;
  }
  for (const BundleImage& image : images) {
    if (image.camera < 0 || image.camera >= static_cast<int>(cameras.size())) {
      return false;
    }
    if (!std::isfinite(image.weight) || image.weight < 1.0 ||
        !image.angular_velocity.allFinite() || !image.linear_velocity.allFinite()) {
      return false;
    }
  }
  for (const BundleObservation& obs : observations) {
    if (obs.image < 0 || obs.image >= static_cast<int>(images.size()) ||
        obs.point < 0 || obs.point >= static_cast<int>(points.size()) ||
        !obs.pixel.allFinite()) {
      return false;
    }
  }
  return true;
}

double ReprojectionError(const BundleProblem& problem,
                         const BundleObservation& observation) {
  const BundleImage& image = problem.images[observation.image];
  const Camera& camera = problem.cameras[image.camera];
  const Eigen::Vector3d in_cam = camera.InCamAtRow(
      image.cam_from_world * problem.points[observation.point], observation.pixel.y(),
      image.angular_velocity, image.linear_velocity);
  if (in_cam.z() <= 0) return std::numeric_limits<double>::infinity();
  return (camera.ImgFromCam(in_cam) - observation.pixel).norm();
}

std::vector<double> ReprojectionErrors(const BundleProblem& problem) {
  std::vector<double> errors;
  errors.reserve(problem.observations.size());
  for (const BundleObservation& observation : problem.observations) {
    errors.push_back(ReprojectionError(problem, observation));
  }
  return errors;
}

}  // namespace flysfm
