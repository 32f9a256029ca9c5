#include "matching/image_decode.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <stdexcept>

#include <libexif/exif-data.h>
#include <opencv2/imgcodecs.hpp>

namespace flysfm {
namespace {

const std::uint8_t kPngSignature[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1A, '\n'};

bool IsJpeg(const std::uint8_t* data, std::size_t size) {
  return size >= 3 && data[0] == 0xFF && data[1] == 0xD8 && data[2] == 0xFF;
}

bool IsPng(const std::uint8_t* data, std::size_t size) {
  return size >= 8 && std::memcmp(data, kPngSignature, 8) == 0;
}

// EXIF rational and short values as double; nullopt when the tag is absent.
std::optional<double> ExifNumber(ExifData* exif, ExifTag tag) {
  ExifEntry* entry = exif_data_get_entry(exif, tag);
  if (entry == nullptr || entry->components < 1 || entry->data == nullptr) return std::nullopt;
  const ExifByteOrder order = exif_data_get_byte_order(exif);
  switch (entry->format) {
    case EXIF_FORMAT_SHORT: return double(exif_get_short(entry->data, order));
    case EXIF_FORMAT_LONG: return double(exif_get_long(entry->data, order));
    case EXIF_FORMAT_RATIONAL: {
      const ExifRational value = exif_get_rational(entry->data, order);
      if (value.denominator == 0) return std::nullopt;
      return double(value.numerator) / value.denominator;
    }
    default: return std::nullopt;
  }
}

std::optional<double> ExifFocalLengthPx(ExifData* exif, int width, int height) {
  std::optional<double> focal_px;
  const auto positive = [](std::optional<double> v) { return v && *v > 0; };
  const std::optional<double> focal_35mm =
      ExifNumber(exif, EXIF_TAG_FOCAL_LENGTH_IN_35MM_FILM);
  const std::optional<double> focal_mm = ExifNumber(exif, EXIF_TAG_FOCAL_LENGTH);
  const std::optional<double> plane_resolution =
      ExifNumber(exif, EXIF_TAG_FOCAL_PLANE_X_RESOLUTION);
  if (positive(focal_35mm)) {
    // The 35 mm equivalent keeps the field of view along the diagonal (a
    // 4:3 or 1:1 frame is cropped from the 36 x 24 mm film differently
    // from a 3:2 one).
    focal_px = *focal_35mm / std::hypot(36.0, 24.0) * std::hypot(width, height);
  } else if (positive(focal_mm) && positive(plane_resolution)) {
    // Resolution unit: 2 inch (the default), 3 cm, 4 mm, 5 um.
    const std::optional<double> unit = ExifNumber(exif, EXIF_TAG_FOCAL_PLANE_RESOLUTION_UNIT);
    const int code = unit ? int(*unit) : 2;
    const double unit_mm = code == 3 ? 10.0 : code == 4 ? 1.0 : code == 5 ? 1e-3 : 25.4;
    // The resolution refers to the sensor's full pixel width, which the
    // stored image may be scaled from.
    const std::optional<double> sensor_width_px = ExifNumber(exif, EXIF_TAG_PIXEL_X_DIMENSION);
    const double scale = positive(sensor_width_px) ? width / *sensor_width_px : 1.0;
    focal_px = *focal_mm * (*plane_resolution / unit_mm) * scale;
  }
  // A 35 mm equivalent outside 8-2 000 mm (a diagonal field of view of 140
  // to 1.2 deg) is no lens a photogrammetric survey uses: a corrupt or
  // misread tag, better replaced by the engine's own guess.
  if (focal_px) {
    const double equivalent_mm = *focal_px / std::hypot(width, height) * std::hypot(36.0, 24.0);
    if (!(equivalent_mm >= 8 && equivalent_mm <= 2000)) focal_px.reset();
  }
  return focal_px;
}

// An EXIF text tag as printable ASCII of at most 40 characters (the
// longest real camera and lens names are about 30): the text is the
// camera's, hostile at worst.
std::string ExifText(ExifData* exif, ExifTag tag) {
  ExifEntry* entry = exif_data_get_entry(exif, tag);
  if (entry == nullptr || entry->format != EXIF_FORMAT_ASCII || entry->data == nullptr) {
    return {};
  }
  std::string text;
  for (unsigned int i = 0; i < entry->size && entry->data[i] != 0 && text.size() < 40; ++i) {
    const unsigned char c = entry->data[i];
    text.push_back(c >= 0x20 && c < 0x7F ? char(c) : '?');
  }
  while (!text.empty() && text.back() == ' ') text.pop_back();
  return text;
}

std::string ExifCameraIdentity(ExifData* exif) {
  std::string identity;
  for (const ExifTag tag : {EXIF_TAG_MAKE, EXIF_TAG_MODEL, EXIF_TAG_BODY_SERIAL_NUMBER,
                            EXIF_TAG_LENS_MODEL}) {
    identity += ExifText(exif, tag) + "|";
  }
  if (const std::optional<double> focal_mm = ExifNumber(exif, EXIF_TAG_FOCAL_LENGTH)) {
    char focal[32];
    std::snprintf(focal, sizeof(focal), "%.1f mm", *focal_mm);
    identity += focal;
  }
  return identity == "||||" ? std::string() : identity;
}

DecodedImage Failure(std::string message) {
  DecodedImage result;
  result.error = std::move(message);
  return result;
}

}  // namespace

bool HasJpegMarkers(const std::uint8_t* data, std::size_t size) {
  if (size < 4 || data[0] != 0xFF || data[1] != 0xD8) return false;
  std::size_t end = size;
  while (end > 2 && data[end - 1] == 0x00) --end;
  return end >= 4 && data[end - 2] == 0xFF && data[end - 1] == 0xD9;
}

bool HasPngMarkers(const std::uint8_t* data, std::size_t size) {
  // The last chunk: length 0, "IEND", 4 bytes of CRC.
  static const std::uint8_t kIend[8] = {0, 0, 0, 0, 'I', 'E', 'N', 'D'};
  return size >= 8 + 12 && std::memcmp(data, kPngSignature, 8) == 0 &&
         std::memcmp(data + size - 12, kIend, 8) == 0;
}

DecodedImage DecodeImageBytes(const std::uint8_t* data, std::size_t size) {
  if (data == nullptr || size == 0) return Failure("empty image data (0 bytes)");
  if (IsJpeg(data, size) && !HasJpegMarkers(data, size)) {
    return Failure("truncated JPEG: no end-of-image marker");
  }
  if (IsPng(data, size) && !HasPngMarkers(data, size)) {
    return Failure("truncated PNG: no IEND chunk");
  }
  cv::Mat decoded;
  try {
    const cv::Mat buffer(1, static_cast<int>(size), CV_8U,
                         const_cast<std::uint8_t*>(data));
    decoded = cv::imdecode(buffer, cv::IMREAD_COLOR | cv::IMREAD_IGNORE_ORIENTATION);
  } catch (const cv::Exception& e) {
    return Failure(std::string("image decoder error: ") + e.what());
  }
  if (decoded.empty()) {
    return Failure("not a decodable image (unknown format or corrupt data, " +
                   std::to_string(size) + " bytes)");
  }
  DecodedImage result;
  result.image = decoded;
  if (IsJpeg(data, size)) {
    if (ExifData* exif = exif_data_new_from_data(data, static_cast<unsigned int>(size))) {
      result.exif_focal_length_px = ExifFocalLengthPx(exif, decoded.cols, decoded.rows);
      result.camera_identity = ExifCameraIdentity(exif);
      exif_data_unref(exif);
    }
  }
  return result;
}

DecodedImage DecodeImageBytes(const std::vector<std::uint8_t>& bytes) {
  return DecodeImageBytes(bytes.data(), bytes.size());
}

DecodedImage DecodeImageFile(const std::string& path) {
  std::ifstream file(path, std::ios::binary);
  if (!file) return Failure("cannot open image file '" + path + "'");
  const std::vector<std::uint8_t> bytes((std::istreambuf_iterator<char>(file)),
                                        std::istreambuf_iterator<char>());
  if (file.bad()) return Failure("cannot read image file '" + path + "'");
  DecodedImage result = DecodeImageBytes(bytes);
  if (!result.ok()) result.error = "'" + path + "': " + result.error;
  return result;
}

std::vector<std::string> ListImageFiles(const std::string& dir) {
  namespace fs = std::filesystem;
  std::error_code error;
  if (!fs::is_directory(dir, error)) {
    throw std::invalid_argument("image folder '" + dir + "' does not exist");
  }
  static const char* kExtensions[] = {".jpg", ".jpeg", ".png", ".tif", ".tiff",
                                      ".bmp", ".pgm",  ".ppm"};
  std::vector<std::string> files;
  for (const fs::directory_entry& entry : fs::directory_iterator(dir, error)) {
    if (!entry.is_regular_file()) continue;
    std::string extension = entry.path().extension().string();
    std::transform(extension.begin(), extension.end(), extension.begin(),
                   [](unsigned char c) { return char(std::tolower(c)); });
    if (std::find(std::begin(kExtensions), std::end(kExtensions), extension) !=
        std::end(kExtensions)) {
      files.push_back(entry.path().string());
    }
  }
  std::sort(files.begin(), files.end());
  return files;
}

}  // namespace flysfm
