#pragma once

#include <cstdint>

#include <opencv2/core.hpp>

namespace flysfm {

// A procedural texture rich in corners and blobs at several scales: the sum
// of smoothed random noise octaves plus random discs, normalised to 8-bit.
// Deterministic for a seed. CV_8UC3 when `color`, else CV_8UC1.
cv::Mat MakeTexture(int width, int height, std::uint32_t seed,
                    bool color = false);

}  // namespace flysfm
