#pragma once

// JPEGs with the EXIF a camera writes, for tests of what the engine reads
// from it (focal length, camera body and lens).

#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include <libexif/exif-tag.h>
#include <opencv2/core.hpp>

namespace flysfm {
namespace testing {

struct ExifTags {
  // Numbers: SHORT for FocalLengthIn35mmFilm and the resolution unit,
  // RATIONAL for the others (EXIF IFD).
  std::vector<std::pair<ExifTag, double>> numbers;
  // Text (ASCII): Make and Model go to IFD 0, the others to the EXIF IFD.
  std::vector<std::pair<ExifTag, std::string>> texts;
};

// `image` encoded as JPEG with an EXIF APP1 segment holding `tags`.
std::vector<std::uint8_t> JpegWithExif(const cv::Mat& image, const ExifTags& tags);

// The same JPEG without its APP1 (EXIF, XMP) segments: a camera that writes
// none, with the same pixels. Throws std::invalid_argument on a malformed
// marker sequence.
std::vector<std::uint8_t> WithoutExif(const std::vector<std::uint8_t>& jpeg);

}  // namespace testing
}  // namespace flysfm
