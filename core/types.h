#pragma once

#include <cstdint>
#include <limits>

namespace flysfm {

// Identifiers of the scene's entities, as COLMAP numbers them (ids start at 1
// in files COLMAP writes; 0 is a valid id here, kInvalid marks "none").
using camera_t = std::uint32_t;
using image_t = std::uint32_t;
using point2D_t = std::uint32_t;
using point3D_t = std::uint64_t;

inline constexpr camera_t kInvalidCameraId = std::numeric_limits<camera_t>::max();
inline constexpr image_t kInvalidImageId = std::numeric_limits<image_t>::max();
inline constexpr point2D_t kInvalidPoint2DIdx = std::numeric_limits<point2D_t>::max();
inline constexpr point3D_t kInvalidPoint3DId = std::numeric_limits<point3D_t>::max();

}  // namespace flysfm
