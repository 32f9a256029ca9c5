#pragma once

// Feature sets of synthetic "places" for retrieval tests: views of one place
// share most of their descriptors (with noise), views of different places
// share none. Cheap enough for hundreds of images.

#include <algorithm>
#include <cmath>
#include <random>
#include <vector>

#include "matching/features.h"

namespace flysfm::testing {

class PlaceFeatures {
 public:
  PlaceFeatures(int num_places, std::uint32_t seed) : rng_(seed) {
    for (int p = 0; p < num_places; ++p) {
      SiftDescriptors pool(300, 128);
      for (int i = 0; i < pool.rows(); ++i) pool.row(i) = RandomDescriptor();
      pools_.push_back(pool);
    }
  }

  // A view of `place`: 240 of its descriptors with noise, 60 unrelated ones,
  // at random positions in a 640x480 frame.
  FeatureSet View(int place) {
    FeatureSet features;
    features.width = 640;
    features.height = 480;
    const int n = 300;
    features.descriptors.resize(n, 128);
    std::uniform_int_distribution<int> pick(0, int(pools_[place].rows()) - 1);
    // Multiplicative, on the SIFT histogram: about 0.02 on the unit RootSIFT
    // vector, as two views of one point differ.
    std::normal_distribution<float> noise(0.f, 0.4f);
    std::uniform_real_distribution<float> x(0.f, 639.f), y(0.f, 479.f);
    for (int i = 0; i < n; ++i) {
      if (i < 240) {
        const auto d = pools_[place].row(pick(rng_));
        for (int k = 0; k < 128; ++k) {
          features.descriptors(i, k) = std::uint8_t(
              std::clamp(std::lround(float(d[k]) * std::exp(noise(rng_))), 0L, 255L));
        }
      } else {
        features.descriptors.row(i) = RandomDescriptor();
      }
      Keypoint kp;
      kp.x = x(rng_);
      kp.y = y(rng_);
      kp.scale = 4.f;
      features.keypoints.push_back(kp);
    }
    return features;
  }

 private:
  // SIFT-like: bytes, sparse-ish (a product of two exponentials), the
  // largest bins near OpenCV's.
  Eigen::Matrix<std::uint8_t, 1, 128> RandomDescriptor() {
    std::exponential_distribution<float> exponential(1.f);
    Eigen::Matrix<std::uint8_t, 1, 128> d;
    for (int k = 0; k < 128; ++k) {
      d[k] = std::uint8_t(std::min(255.f, std::round(20.f * exponential(rng_) * exponential(rng_))));
    }
    return d;
  }

  std::mt19937 rng_;
  std::vector<SiftDescriptors> pools_;
};

}  // namespace flysfm::testing
