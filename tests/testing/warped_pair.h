#pragma once

// A textured image and its warp by a known homography: ground truth for
// feature positions and matches.

#include <cstdint>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <opencv2/core.hpp>

namespace flysfm::testing {

struct WarpedPair {
  cv::Mat image1;
  cv::Mat image2;
  // Maps pixel coordinates of image1 to image2 (OpenCV convention: pixel
  // centres at integer coordinates).
  Eigen::Matrix3d homography;
};

// image1 is MakeTexture(width, height, seed, color); image2 (width2 x height2)
// shows it rotated by `angle_deg` about its centre, scaled by `scale` and
// placed at the centre of image2, warped with bicubic interpolation.
WarpedPair MakeWarpedPair(int width, int height, double angle_deg, double scale,
                          int width2, int height2, std::uint32_t seed, bool color = false);

Eigen::Vector2d ApplyHomography(const Eigen::Matrix3d& h, const Eigen::Vector2d& x);

}  // namespace flysfm::testing
