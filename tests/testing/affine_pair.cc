#include "tests/testing/affine_pair.h"

#include <stdexcept>

#include <opencv2/imgproc.hpp>

#include "io/synthetic/procedural_texture.h"

namespace flysfm::testing {

AffinePair MakeAffinePair(const AffinePairOptions& options) {
  if (options.oversampling < 1 || options.width < 1 || options.height < 1) {
    throw std::invalid_argument("invalid AffinePairOptions");
  }
  AffinePair pair;
  const Eigen::Vector2d center(0.5 * (options.width - 1),
                               0.5 * (options.height - 1));
  pair.linear = options.linear;
  pair.offset = center + options.translation - options.linear * center;

  // Fine pixel f covers coarse pixel f / k, whose centre is fine coordinate
  // k c + (k - 1) / 2: x_fine = k x + (k - 1) / 2.
  const double k = options.oversampling;
  const double half = 0.5 * (k - 1);
  const cv::Size fine_size(options.width * options.oversampling,
                           options.height * options.oversampling);
  cv::Mat fine;
  MakeTexture(fine_size.width, fine_size.height, options.seed)
      .convertTo(fine, CV_32F);
  if (options.blur_sigma > 0) {
    cv::GaussianBlur(fine, fine, cv::Size(), options.blur_sigma * k);
  }
  const Eigen::Vector2d fine_offset = k * pair.offset +
                                      Eigen::Vector2d(half, half) -
                                      pair.linear * Eigen::Vector2d(half, half);
  const cv::Matx23d forward(pair.linear(0, 0), pair.linear(0, 1),
                            fine_offset.x(), pair.linear(1, 0),
                            pair.linear(1, 1), fine_offset.y());
  cv::Mat fine_warped;
  cv::warpAffine(fine, fine_warped, cv::Mat(forward), fine_size,
                 cv::INTER_CUBIC, cv::BORDER_REFLECT);

  const cv::Size size(options.width, options.height);
  cv::resize(fine, pair.image1, size, 0, 0, cv::INTER_AREA);
  cv::Mat warped;
  cv::resize(fine_warped, warped, size, 0, 0, cv::INTER_AREA);
  warped.convertTo(pair.image2, CV_32F, options.contrast, options.brightness);
  return pair;
}

}  // namespace flysfm::testing
