#include "tests/testing/warped_pair.h"

#include <cmath>

#include <opencv2/core/eigen.hpp>
#include <opencv2/imgproc.hpp>

#include "io/synthetic/procedural_texture.h"

namespace flysfm::testing {

WarpedPair MakeWarpedPair(int width, int height, double angle_deg, double scale,
                          int width2, int height2, std::uint32_t seed, bool color) {
  WarpedPair pair;
  pair.image1 = MakeTexture(width, height, seed, color);
  const double a = angle_deg * M_PI / 180.0;
  Eigen::Matrix3d to_origin = Eigen::Matrix3d::Identity();
  to_origin(0, 2) = -(width - 1) / 2.0;
  to_origin(1, 2) = -(height - 1) / 2.0;
  Eigen::Matrix3d rotate_scale = Eigen::Matrix3d::Identity();
  rotate_scale.topLeftCorner<2, 2>() << scale * std::cos(a), -scale * std::sin(a),
      scale * std::sin(a), scale * std::cos(a);
  Eigen::Matrix3d to_centre2 = Eigen::Matrix3d::Identity();
  to_centre2(0, 2) = (width2 - 1) / 2.0;
  to_centre2(1, 2) = (height2 - 1) / 2.0;
  pair.homography = to_centre2 * rotate_scale * to_origin;
  cv::Mat h;
  cv::eigen2cv(pair.homography, h);
  cv::warpPerspective(pair.image1, pair.image2, h, cv::Size(width2, height2), cv::INTER_CUBIC,
                      cv::BORDER_CONSTANT, cv::Scalar::all(128));
  return pair;
}

Eigen::Vector2d ApplyHomography(const Eigen::Matrix3d& h, const Eigen::Vector2d& x) {
  return (h * x.homogeneous()).hnormalized();
}

}  // namespace flysfm::testing
