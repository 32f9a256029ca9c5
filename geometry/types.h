#pragma once

#include <cstdint>
#include <limits>

#include <Eigen/Core>

namespace flysfm {

using Matrix3x4d = Eigen::Matrix<double, 3, 4>;
using Vector6d = Eigen::Matrix<double, 6, 1>;

// Identifiers of the scene's entities, as COLMAP numbers them (ids start at 1
// in files COLMAP writes; 0 is a valid id here, kInvalid marks "none"). They
// live at the bottom of the module graph so that matching and retrieval name
// images as core does.
using camera_t = std::uint32_t;
using image_t = std::uint32_t;
using point2D_t = std::uint32_t;
using point3D_t = std::uint64_t;
// A sub-model: registered images and the points they observe, in a frame of
// their own until merged with another.
using model_t = std::uint32_t;

inline constexpr camera_t kInvalidCameraId = std::numeric_limits<camera_t>::max();
inline constexpr image_t kInvalidImageId = std::numeric_limits<image_t>::max();
inline constexpr point2D_t kInvalidPoint2DIdx = std::numeric_limits<point2D_t>::max();
inline constexpr point3D_t kInvalidPoint3DId = std::numeric_limits<point3D_t>::max();
inline constexpr model_t kInvalidModelId = std::numeric_limits<model_t>::max();

}  // namespace flysfm
