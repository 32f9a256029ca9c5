// Image bytes as a camera or a watched folder may deliver them: no input may
// crash the decoder or make it allocate past its pixel bound, and a decoded
// image must agree with the size its header claims.

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <optional>

#include <opencv2/core.hpp>

#include "fuzz/camera_identity_check.h"
#include "matching/image_decode.h"

namespace {

// Far below the default 200 MP: a fuzzed header claiming the maximum still
// decodes within the fuzzer's memory limit (4 MP of BGR is 12 MB).
constexpr double kMaxImagePixels = 4e6;

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  flysfm::DecodeOptions options;
  options.max_image_pixels = kMaxImagePixels;
  const flysfm::DecodedImage decoded = flysfm::DecodeImageBytes(data, size, options);
  if (decoded.ok() != decoded.error.empty() || decoded.ok() == decoded.image.empty()) {
    __builtin_trap();
  }
  if (!decoded.ok()) {
    if (decoded.exif_focal_length_px || !decoded.camera_identity.empty()) __builtin_trap();
    return 0;
  }
  const cv::Mat& image = decoded.image;
  if (image.type() != CV_8UC3 || double(image.cols) * image.rows > kMaxImagePixels) {
    __builtin_trap();
  }
  const std::optional<flysfm::ImageSize> claimed = flysfm::ReadImageSize(data, size);
  if (claimed && (claimed->width != std::uint32_t(image.cols) ||
                  claimed->height != std::uint32_t(image.rows))) {
    __builtin_trap();
  }
  if (!PlausibleCameraIdentity(decoded.camera_identity)) {
    __builtin_trap();
  }
  if (decoded.exif_focal_length_px && !(std::isfinite(*decoded.exif_focal_length_px) &&
                                        *decoded.exif_focal_length_px > 0)) {
    __builtin_trap();
  }
  return 0;
}
