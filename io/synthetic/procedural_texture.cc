#include "io/synthetic/procedural_texture.h"

#include <random>

#include <opencv2/imgproc.hpp>

namespace flysfm {
namespace {

cv::Mat GreyTexture(int width, int height, std::mt19937& rng) {
  cv::Mat sum = cv::Mat::zeros(height, width, CV_32F);
  std::uniform_real_distribution<float> uniform(0.f, 1.f);
  // Octaves from coarse to fine: noise sampled on a grid of `cell` pixels,
  // upsampled smoothly; finer octaves weigh less.
  float weight = 1.f;
  for (int cell = 64; cell >= 2; cell /= 2) {
    cv::Mat coarse(height / cell + 2, width / cell + 2, CV_32F);
    for (int r = 0; r < coarse.rows; ++r) {
      for (int c = 0; c < coarse.cols; ++c) coarse.at<float>(r, c) = uniform(rng);
    }
    cv::Mat fine;
    cv::resize(coarse, fine, cv::Size(coarse.cols * cell, coarse.rows * cell), 0,
               0, cv::INTER_CUBIC);
    sum += weight * fine(cv::Rect(0, 0, width, height));
    weight *= 0.85f;
  }
  // Discs give SIFT clean blob responses at many scales.
  const int num_discs = width * height / 2000;
  for (int i = 0; i < num_discs; ++i) {
    const cv::Point center(int(uniform(rng) * width), int(uniform(rng) * height));
    const int radius = 2 + int(uniform(rng) * uniform(rng) * 25);
    cv::circle(sum, center, radius, cv::Scalar(uniform(rng) * 3.f - 1.5f),
               cv::FILLED, cv::LINE_AA);
  }
  cv::Mat result;
  cv::normalize(sum, sum, 10, 245, cv::NORM_MINMAX);
  sum.convertTo(result, CV_8U);
  return result;
}

}  // namespace

cv::Mat MakeTexture(int width, int height, std::uint32_t seed, bool color) {
  std::mt19937 rng(seed);
  if (!color) return GreyTexture(width, height, rng);
  std::vector<cv::Mat> channels;
  const cv::Mat base = GreyTexture(width, height, rng);
  for (int c = 0; c < 3; ++c) {
    cv::Mat tint;
    cv::addWeighted(base, 0.7, GreyTexture(width, height, rng), 0.3, 0, tint);
    channels.push_back(tint);
  }
  cv::Mat result;
  cv::merge(channels, result);
  return result;
}

}  // namespace flysfm
