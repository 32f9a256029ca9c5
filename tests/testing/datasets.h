#pragma once

// Readers for the ground truth of the shared real data sets (see
// ../shared/data/README.md). A missing or malformed file throws
// std::runtime_error naming it.

#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace flysfm::testing {

// One line of a TUM rgb.txt: timestamp and path relative to the sequence.
struct TumFrame {
  double timestamp = 0;
  std::string file;
};
std::vector<TumFrame> ReadTumFrames(const std::string& rgb_txt);

// One line of a TUM groundtruth.txt: camera-to-world pose.
struct TumPose {
  double timestamp = 0;
  Eigen::Vector3d position = Eigen::Vector3d::Zero();
  Eigen::Quaterniond world_from_cam = Eigen::Quaterniond::Identity();
};
std::vector<TumPose> ReadTumGroundTruth(const std::string& groundtruth_txt);

// For each frame, the index of the pose nearest in time if within
// `max_difference` seconds (TUM's convention: 0.02), else -1. `poses` sorted
// by time, as in the files.
std::vector<int> AssociateTum(const std::vector<TumFrame>& frames,
                              const std::vector<TumPose>& poses, double max_difference = 0.02);

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
