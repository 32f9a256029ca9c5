#include "tests/testing/datasets.h"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <sstream>
#include <stdexcept>

namespace flysfm::testing {
namespace {

std::ifstream Open(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw std::runtime_error("cannot open '" + path + "'");
  return in;
}

// Lines that are neither empty nor '#' comments.
std::vector<std::string> DataLines(const std::string& path) {
  std::ifstream in = Open(path);
  std::vector<std::string> lines;
  for (std::string line; std::getline(in, line);) {
    const auto first = line.find_first_not_of(" \t\r");
    if (first == std::string::npos || line[first] == '#') continue;
    lines.push_back(line);
  }
  return lines;
}

[[noreturn]] void Malformed(const std::string& path, const std::string& line) {
  throw std::runtime_error("malformed line in '" + path + "': " + line);
}

}  // namespace

std::vector<TumFrame> ReadTumFrames(const std::string& rgb_txt) {
  std::vector<TumFrame> frames;
  for (const std::string& line : DataLines(rgb_txt)) {
    std::istringstream stream(line);
    TumFrame frame;
    if (!(stream >> frame.timestamp >> frame.file)) Malformed(rgb_txt, line);
    frames.push_back(frame);
  }
  return frames;
}

std::vector<TumPose> ReadTumGroundTruth(const std::string& groundtruth_txt) {
  std::vector<TumPose> poses;
  for (const std::string& line : DataLines(groundtruth_txt)) {
    std::istringstream stream(line);
    TumPose pose;
    double qx, qy, qz, qw;
    if (!(stream >> pose.timestamp >> pose.position.x() >> pose.position.y() >>
          pose.position.z() >> qx >> qy >> qz >> qw)) {
      Malformed(groundtruth_txt, line);
    }
    pose.world_from_cam = Eigen::Quaterniond(qw, qx, qy, qz).normalized();
    poses.push_back(pose);
  }
  return poses;
}

std::vector<int> AssociateTum(const std::vector<TumFrame>& frames,
                              const std::vector<TumPose>& poses, double max_difference) {
  std::vector<int> result;
  for (const TumFrame& frame : frames) {
    const auto after = std::lower_bound(
        poses.begin(), poses.end(), frame.timestamp,
        [](const TumPose& pose, double t) { return pose.timestamp < t; });
    int best = -1;
    double best_difference = max_difference;
    for (auto it : {after, after == poses.begin() ? after : std::prev(after)}) {
      if (it == poses.end()) continue;
      const double difference = std::abs(it->timestamp - frame.timestamp);
      if (difference <= best_difference) {
        best_difference = difference;
        best = int(it - poses.begin());
      }
    }
    result.push_back(best);
  }
  return result;
}

StrechaCamera ReadStrechaCamera(const std::string& path) {
  std::ifstream in = Open(path);
  StrechaCamera camera;
  double k1, k2, k3;
  for (int r = 0; r < 3; ++r) in >> camera.K(r, 0) >> camera.K(r, 1) >> camera.K(r, 2);
  in >> k1 >> k2 >> k3;
  for (int r = 0; r < 3; ++r) in >> camera.R(r, 0) >> camera.R(r, 1) >> camera.R(r, 2);
  in >> camera.centre.x() >> camera.centre.y() >> camera.centre.z() >> camera.width >>
      camera.height;
  if (!in) throw std::runtime_error("malformed Strecha camera file '" + path + "'");
  return camera;
}

std::vector<MiddleburyCamera> ReadMiddleburyCameras(const std::string& par_txt) {
  std::vector<std::string> lines = DataLines(par_txt);
  // The first line is the number of cameras.
  if (lines.empty()) throw std::runtime_error("empty Middlebury file '" + par_txt + "'");
  std::vector<MiddleburyCamera> cameras;
  for (std::size_t i = 1; i < lines.size(); ++i) {
    std::istringstream stream(lines[i]);
    MiddleburyCamera camera;
    stream >> camera.name;
    for (int r = 0; r < 3; ++r) stream >> camera.K(r, 0) >> camera.K(r, 1) >> camera.K(r, 2);
    for (int r = 0; r < 3; ++r) stream >> camera.R(r, 0) >> camera.R(r, 1) >> camera.R(r, 2);
    stream >> camera.t.x() >> camera.t.y() >> camera.t.z();
    if (!stream) Malformed(par_txt, lines[i]);
    cameras.push_back(camera);
  }
  return cameras;
}

}  // namespace flysfm::testing
