#pragma once

// Readers for the ground truth of the real data sets (their layout:
// docs/testing.md, "Real data") that io does not read itself: TUM sequences and
// trajectories are io's (ListTumSequence, ReadTumTrajectory). A missing or
// malformed file throws std::runtime_error naming it.

#include <filesystem>
#include <map>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "geometry/rigid3d.h"
#include "io/sources/image_source.h"

namespace flysfm::testing {

// A Strecha .camera file: K, R (camera-to-world rotation), centre C; the
// projection is K [R^T | -R^T C].
struct StrechaCamera {
  Eigen::Matrix3d K = Eigen::Matrix3d::Identity();
  Eigen::Matrix3d R = Eigen::Matrix3d::Identity();
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();
  int width = 0;
  int height = 0;

  Rigid3d CamFromWorld() const {
    return Rigid3d(Eigen::Matrix3d(R.transpose()), -R.transpose() * centre);
  }
};
StrechaCamera ReadStrechaCamera(const std::string& path);

// One line of a Middlebury <name>_par.txt: P = K [R | t], world-to-camera.
struct MiddleburyCamera {
  std::string name;
  Eigen::Matrix3d K = Eigen::Matrix3d::Identity();
  Eigen::Matrix3d R = Eigen::Matrix3d::Identity();
  Eigen::Vector3d t = Eigen::Vector3d::Zero();

  Eigen::Vector3d Centre() const { return -R.transpose() * t; }
  Rigid3d CamFromWorld() const { return Rigid3d(R, t); }
};
std::vector<MiddleburyCamera> ReadMiddleburyCameras(const std::string& par_txt);

// A 3x3 intrinsic matrix as the photo sets' images/K.txt hold it.
Eigen::Matrix3d ReadIntrinsicMatrix(const std::string& path);

// A real photo set of ../shared/data as the tests and benchmarks feed it:
// its images, its shared camera as --camera takes it, that camera's mean
// focal length, and the true poses by image name where the set has them
// (none for sceaux_castle).
struct PhotoSet {
  std::string name;
  std::vector<Frame> frames;
  std::string camera;
  double focal_length = 0;
  std::map<std::string, Rigid3d> cam_from_world;

  // The true camera centres by image name.
  std::map<std::string, Eigen::Vector3d> Centres() const;
};
// `data` is the shared data folder (testing::DataPath's root).
PhotoSet FountainP11(const std::filesystem::path& data);
PhotoSet SceauxCastle(const std::filesystem::path& data);
PhotoSet TempleRing19(const std::filesystem::path& data);

}  // namespace flysfm::testing
