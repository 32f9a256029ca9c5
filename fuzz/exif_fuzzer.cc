// EXIF as a camera may write it, fed to libexif without a JPEG around it so
// that every input reaches the tag parsing: no input may crash it, and what
// the engine takes from it stays printable, bounded and a usable focal length.

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <string>

#include "fuzz/camera_identity_check.h"
#include "matching/image_decode.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  // The image size scales the focal length; the first four bytes choose it
  // (0 to 65535 each way, the range a JPEG header can claim) so that the
  // arithmetic meets degenerate and extreme sizes too.
  if (size < 4) return 0;
  const int width = data[0] << 8 | data[1];
  const int height = data[2] << 8 | data[3];
  const flysfm::ExifFields fields = flysfm::ReadExif(data + 4, size - 4, width, height);
  if (!PlausibleCameraIdentity(fields.camera_identity)) {
    __builtin_trap();
  }
  if (fields.focal_length_px) {
    const double focal = *fields.focal_length_px;
    // The bound ReadExif applies: a 35 mm equivalent of 8-2 000 mm.
    const double equivalent_mm = focal / std::hypot(width, height) * std::hypot(36.0, 24.0);
    if (!std::isfinite(focal) || !(focal > 0) || !(equivalent_mm >= 8 - 1e-9) ||
        !(equivalent_mm <= 2000 + 1e-9)) {
      __builtin_trap();
    }
  }
  return 0;
}
