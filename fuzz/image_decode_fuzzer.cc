// Image bytes as a camera or a watched folder may deliver them: no input may
// crash the decoder or make it allocate past its pixel bound, and a decoded
// image must agree with the size its header claims, in grey and in its
// (perhaps reduced) colour.

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

namespace {

// Whatever the bytes, a result is either an error or a grey image of the
// claimed size with a colour one reduced by colour_reduction.
void CheckDecode(const std::uint8_t* data, std::size_t size, int colour_long_side) {
  flysfm::DecodeOptions options;
  options.max_image_pixels = kMaxImagePixels;
  const flysfm::DecodedImage decoded =
      flysfm::DecodeImageBytes(data, size, options, colour_long_side);
  if (decoded.ok() != decoded.error.empty() || decoded.ok() == decoded.image.empty() ||
      decoded.ok() == decoded.grey.empty()) {
    __builtin_trap();
  }
  if (!decoded.ok()) {
    if (decoded.exif_focal_length_px || !decoded.camera_identity.empty()) __builtin_trap();
    return;
  }
  const cv::Mat& grey = decoded.grey;
  const int r = decoded.colour_reduction;
  if (grey.type() != CV_8UC1 || double(grey.cols) * grey.rows > kMaxImagePixels ||
      decoded.image.type() != CV_8UC3 || (r != 1 && r != 2 && r != 4 && r != 8) ||
      (colour_long_side == 0 && r != 1) ||
      decoded.image.size() != flysfm::DctReducedSize(grey.size(), r)) {
    __builtin_trap();
  }
  const std::optional<flysfm::ImageSize> claimed = flysfm::ReadImageSize(data, size);
  if (claimed && (claimed->width != std::uint32_t(grey.cols) ||
                  claimed->height != std::uint32_t(grey.rows))) {
    __builtin_trap();
  }
  if (!PlausibleCameraIdentity(decoded.camera_identity)) {
    __builtin_trap();
  }
  if (decoded.exif_focal_length_px && !(std::isfinite(*decoded.exif_focal_length_px) &&
                                        *decoded.exif_focal_length_px > 0)) {
    __builtin_trap();
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  // At full size, and as the engine decodes (colour reduced where it can be).
  CheckDecode(data, size, 0);
  CheckDecode(data, size, 64);
  return 0;
}
