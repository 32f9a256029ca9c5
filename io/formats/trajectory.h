#pragma once

// Trajectories in the TUM RGB-D format: one line per pose,
// "timestamp tx ty tz qx qy qz qw", camera-to-world, metres; '#' comments.

#include <filesystem>
#include <string>
#include <utility>
#include <vector>

#include "core/scene/reconstruction.h"
#include "geometry/rigid3d.h"

namespace flysfm {

struct StampedPose {
  double timestamp = 0;
  Rigid3d world_from_cam;
};

// Throws std::runtime_error naming the file and line of a malformed line.
std::vector<StampedPose> ReadTumTrajectory(const std::filesystem::path& path);
void WriteTumTrajectory(const std::vector<StampedPose>& poses,
                        const std::filesystem::path& path);

// The timestamp an image name stands for: its numeric stem
// ("1305031102.175304.png" -> 1305031102.175304); `fallback` when the stem is
// not a number.
double TimestampFromImageName(const std::string& name, double fallback);

// The registered images' poses in registration order, timestamped by
// TimestampFromImageName with the image's capture time as fallback (its
// source's timestamp: a folder's index), else its registration index.
std::vector<StampedPose> TrajectoryOf(const Reconstruction& reconstruction);

// Pairs (index into `estimated`, index into `reference`) whose timestamps
// differ by at most `max_difference` seconds, each nearest in time, each
// reference pose used once (TUM's associate.py does the same).
std::vector<std::pair<std::size_t, std::size_t>> AssociateByTimestamp(
    const std::vector<StampedPose>& estimated,
    const std::vector<StampedPose>& reference, double max_difference = 0.02);

}  // namespace flysfm
