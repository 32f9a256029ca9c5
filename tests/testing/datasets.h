#pragma once

// Readers for the ground truth of the shared real data sets (see
// ../shared/data/README.md) that io does not read itself: TUM sequences and
// trajectories are io's (ListTumSequence, ReadTumTrajectory). A missing or
// malformed file throws std::runtime_error naming it.

#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace flysfm::testing {

// A Strecha .camera file: K, R (camera-to-world rotation), centre C; the
// projection is K [R^T | -R^T C].
struct StrechaCamera {
  Eigen::Matrix3d K = Eigen::Matrix3d::Identity();
  Eigen::Matrix3d R = Eigen::Matrix3d::Identity();
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();
  int width = 0;
  int height = 0;
};
StrechaCamera ReadStrechaCamera(const std::string& path);

// One line of a Middlebury <name>_par.txt: P = K [R | t], world-to-camera.
struct MiddleburyCamera {
  std::string name;
  Eigen::Matrix3d K = Eigen::Matrix3d::Identity();
  Eigen::Matrix3d R = Eigen::Matrix3d::Identity();
  Eigen::Vector3d t = Eigen::Vector3d::Zero();

  Eigen::Vector3d Centre() const { return -R.transpose() * t; }
};
std::vector<MiddleburyCamera> ReadMiddleburyCameras(const std::string& par_txt);

}  // namespace flysfm::testing
