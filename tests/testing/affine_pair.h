#pragma once

// A pair of grey images related by a known affine map and a known linear
// brightness change, for least-squares matching and other sub-pixel tests.

#include <cstdint>

#include <Eigen/Core>
#include <opencv2/core.hpp>

namespace flysfm::testing {

struct AffinePairOptions {
  int width = 400;
  int height = 400;
  // Linear part and translation of image2_from_image1 about the image
  // centre: x2 = linear (x1 - c) + c + translation.
  Eigen::Matrix2d linear = Eigen::Matrix2d::Identity();
  Eigen::Vector2d translation = Eigen::Vector2d::Zero();
  // image2 = brightness + contrast * warped image1 (grey levels).
  double brightness = 0.0;
  double contrast = 1.0;
  // Standard deviation (image-1 pixels) of a Gaussian blur standing in for
  // the lens' point spread. It is applied before the warp, so that the two
  // images are related by exactly the affine map (image 2's blur is scaled
  // with it); keep it >= 1 / (smallest scale) for a blur of at least one
  // pixel in both images, as in any real camera.
  double blur_sigma = 1.0;
  // Both images are rendered at this many times the resolution and reduced
  // by pixel-area averaging, as a sensor integrates light: resampling errors
  // of the warp then stay far below the tolerances of sub-pixel tests.
  int oversampling = 4;
  std::uint32_t seed = 0;
};

struct AffinePair {
  cv::Mat image1;  // CV_32F, grey levels 0..255
  cv::Mat image2;  // CV_32F
  Eigen::Matrix2d linear;
  Eigen::Vector2d offset;  // x2 = linear x1 + offset

  Eigen::Vector2d Map(const Eigen::Vector2d& point1) const {
    return linear * point1 + offset;
  }
};

// Both images view the texture MakeTexture(oversampling * width, ...,
// seed): image 1 directly, image 2 through the affine map. Positions use
// OpenCV's pixel-centre convention.
AffinePair MakeAffinePair(const AffinePairOptions& options);

}  // namespace flysfm::testing
