#include "io/formats/trajectory.h"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <iomanip>
#include <limits>
#include <sstream>
#include <stdexcept>

#include "io/formats/atomic_file.h"
#include "io/formats/data_lines.h"

namespace flysfm {

std::vector<StampedPose> ReadTumTrajectory(const std::filesystem::path& path) {
  std::ifstream in(path);
  if (!in) throw std::runtime_error("cannot open trajectory " + path.string());
  std::vector<StampedPose> poses;
  ForEachDataLine(in, [&](const std::string& line, int number) {
    std::istringstream fields(line);
    StampedPose pose;
    double tx, ty, tz, qx, qy, qz, qw;
    if (!(fields >> pose.timestamp >> tx >> ty >> tz >> qx >> qy >> qz >> qw) ||
        !std::isfinite(pose.timestamp) || std::abs(qw * qw + qx * qx + qy * qy + qz * qz) < 1e-12) {
      throw std::runtime_error(path.string() + ":" + std::to_string(number) +
                               ": expected 'timestamp tx ty tz qx qy qz qw'");
    }
    pose.world_from_cam =
        Rigid3d(Eigen::Quaterniond(qw, qx, qy, qz), Eigen::Vector3d(tx, ty, tz));
    poses.push_back(pose);
  });
  return poses;
}

void WriteTumTrajectory(const std::vector<StampedPose>& poses,
                        const std::filesystem::path& path) {
  WriteFileAtomically(path, [&](std::ostream& out) {
    out << "# timestamp tx ty tz qx qy qz qw (camera-to-world)\n";
    for (const StampedPose& pose : poses) {
      const Eigen::Quaterniond& q = pose.world_from_cam.rotation;
      const Eigen::Vector3d& t = pose.world_from_cam.translation;
      out << std::fixed << std::setprecision(6) << pose.timestamp
          << std::defaultfloat << std::setprecision(17) << ' ' << t.x() << ' '
          << t.y() << ' ' << t.z() << ' ' << q.x() << ' ' << q.y() << ' '
          << q.z() << ' ' << q.w() << '\n';
    }
  });
}

double TimestampFromImageName(const std::string& name, double fallback) {
  const std::string file = std::filesystem::path(name).filename().string();
  const std::string stem = file.substr(0, file.find_last_of('.'));
  std::size_t used = 0;
  double value = 0;
  try {
    value = std::stod(stem, &used);
  } catch (const std::exception&) {
    return fallback;
  }
  return used == stem.size() && std::isfinite(value) ? value : fallback;
}

std::vector<StampedPose> TrajectoryOf(const Reconstruction& reconstruction) {
  std::vector<StampedPose> poses;
  for (const image_t id : reconstruction.RegisteredImageIds()) {
    const Image& image = reconstruction.image(id);
    // Registration order is not capture order (the first pair's reference
    // is whichever image initialised it): the capture time, when the
    // source gave one, keeps a photo folder's stamps its shooting order.
    const double fallback = image.capture_time ? *image.capture_time : double(poses.size());
    poses.push_back({TimestampFromImageName(image.name, fallback), Inverse(*image.cam_from_world)});
  }
  return poses;
}

std::vector<std::pair<std::size_t, std::size_t>> AssociateByTimestamp(
    const std::vector<StampedPose>& estimated,
    const std::vector<StampedPose>& reference, double max_difference) {
  // All candidate pairs within the tolerance, closest first; greedy, like
  // associate.py.
  std::vector<std::tuple<double, std::size_t, std::size_t>> candidates;
  std::vector<std::size_t> order(reference.size());
  for (std::size_t j = 0; j < order.size(); ++j) order[j] = j;
  std::sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) {
    return reference[a].timestamp < reference[b].timestamp;
  });
  for (std::size_t i = 0; i < estimated.size(); ++i) {
    const double t = estimated[i].timestamp;
    auto it = std::lower_bound(order.begin(), order.end(), t - max_difference,
                               [&](std::size_t j, double value) {
                                 return reference[j].timestamp < value;
                               });
    for (; it != order.end() && reference[*it].timestamp <= t + max_difference; ++it) {
      candidates.emplace_back(std::abs(reference[*it].timestamp - t), i, *it);
    }
  }
  std::sort(candidates.begin(), candidates.end());
  std::vector<bool> used_estimated(estimated.size()), used_reference(reference.size());
  std::vector<std::pair<std::size_t, std::size_t>> pairs;
  for (const auto& [difference, i, j] : candidates) {
    if (used_estimated[i] || used_reference[j]) continue;
    used_estimated[i] = used_reference[j] = true;
    pairs.emplace_back(i, j);
  }
  std::sort(pairs.begin(), pairs.end());
  return pairs;
}

}  // namespace flysfm
