#pragma once

#include <array>
#include <cstdint>
#include <vector>

#include <Eigen/Core>

#include "geometry/types.h"

namespace flysfm {

struct TrackElement {
  image_t image_id = kInvalidImageId;
  point2D_t point2D_idx = kInvalidPoint2DIdx;

  bool operator==(const TrackElement& other) const {
    return image_id == other.image_id && point2D_idx == other.point2D_idx;
  }
};

struct Point3D {
  Eigen::Vector3d xyz = Eigen::Vector3d::Zero();
  std::array<std::uint8_t, 3> color = {0, 0, 0};
  // Mean reprojection error of the track in pixels, refreshed by
  // Reconstruction::UpdatePointErrors; -1 until then.
  double error = -1.0;
  std::vector<TrackElement> track;
};

}  // namespace flysfm
