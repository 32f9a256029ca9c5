#include "matching/image_decode.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <limits>
#include <stdexcept>

#include <libexif/exif-data.h>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

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
    // Compared as read: a hostile value does not fit an int.
    const double code = unit.value_or(2.0);
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

// Days from 1970-01-01 to a date of the proleptic Gregorian calendar
// (H. Hinnant's days_from_civil): no time zone of the process gets in.
std::int64_t DaysFromCivil(std::int64_t year, unsigned month, unsigned day) {
  year -= month <= 2;
  const std::int64_t era = (year >= 0 ? year : year - 399) / 400;
  const unsigned year_of_era = unsigned(year - era * 400);
  const unsigned day_of_year = (153 * (month > 2 ? month - 3 : month + 9) + 2) / 5 + day - 1;
  const unsigned day_of_era = year_of_era * 365 + year_of_era / 4 - year_of_era / 100 + day_of_year;
  return era * 146097 + std::int64_t(day_of_era) - 719468;
}

std::optional<double> ExifCaptureTime(ExifData* exif) {
  const std::string text = ExifText(exif, EXIF_TAG_DATE_TIME_ORIGINAL);
  int year = 0, month = 0, day = 0, hour = 0, minute = 0, second = 0;
  if (std::sscanf(text.c_str(), "%4d:%2d:%2d %2d:%2d:%2d", &year, &month, &day, &hour, &minute,
                  &second) != 6) {
    return std::nullopt;
  }
  // A leap second is 60.
  if (year < 1 || month < 1 || month > 12 || day < 1 || day > 31 || hour < 0 || hour > 23 ||
      minute < 0 || minute > 59 || second < 0 || second > 60) {
    return std::nullopt;
  }
  double time = double(DaysFromCivil(year, unsigned(month), unsigned(day))) * 86400.0 +
                hour * 3600.0 + minute * 60.0 + second;
  // "SubSecTimeOriginal": the digits of the fraction ("05" is 0.05 s).
  const std::string sub_second = ExifText(exif, EXIF_TAG_SUB_SEC_TIME_ORIGINAL);
  double scale = 0.1;
  for (const char c : sub_second) {
    if (c < '0' || c > '9') break;
    time += (c - '0') * scale;
    scale /= 10;
  }
  return time;
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

bool DecodeOptions::Check(std::string* error) const {
  const char* bad = !(max_image_pixels >= 1) ? "max_image_pixels must be >= 1"
                    : max_file_bytes < 1     ? "max_file_bytes must be >= 1"
                                             : nullptr;
  if (bad != nullptr && error != nullptr) *error = bad;
  return bad == nullptr;
}

namespace {

std::uint32_t BigEndian(const std::uint8_t* bytes, int count) {
  std::uint32_t value = 0;
  for (int i = 0; i < count; ++i) value = value << 8 | bytes[i];
  return value;
}

// Walks the marker segments after SOI up to the first frame header; every
// length is checked against the buffer before it is followed.
std::optional<ImageSize> JpegSize(const std::uint8_t* data, std::size_t size) {
  std::size_t at = 2;
  while (at + 4 <= size) {
    if (data[at] != 0xFF) return std::nullopt;
    const std::uint8_t marker = data[at + 1];
    if (marker == 0xFF) {  // fill byte before a marker
      ++at;
      continue;
    }
    if (marker == 0x01 || (marker >= 0xD0 && marker <= 0xD7)) {  // no length
      at += 2;
      continue;
    }
    // Scan data or the end before any frame header: no size to trust.
    if (marker == 0xDA || marker == 0xD9) return std::nullopt;
    const std::size_t length = BigEndian(data + at + 2, 2);
    if (length < 2) return std::nullopt;
    // SOF0-SOF15 but DHT (C4), JPG (C8) and DAC (CC): precision, height, width.
    const bool frame_header =
        marker >= 0xC0 && marker <= 0xCF && marker != 0xC4 && marker != 0xC8 && marker != 0xCC;
    if (frame_header) {
      if (length < 7 || at + 9 > size) return std::nullopt;
      ImageSize image_size;
      image_size.height = BigEndian(data + at + 5, 2);
      image_size.width = BigEndian(data + at + 7, 2);
      return image_size;
    }
    at += 2 + length;
  }
  return std::nullopt;
}

std::optional<ImageSize> PngSize(const std::uint8_t* data, std::size_t size) {
  // Signature, then the IHDR chunk: length, "IHDR", width, height.
  if (size < 24 || std::memcmp(data + 12, "IHDR", 4) != 0) return std::nullopt;
  ImageSize image_size;
  image_size.width = BigEndian(data + 16, 4);
  image_size.height = BigEndian(data + 20, 4);
  return image_size;
}

}  // namespace

std::optional<ImageSize> ReadImageSize(const std::uint8_t* data, std::size_t size) {
  if (data == nullptr) return std::nullopt;
  if (IsJpeg(data, size)) return JpegSize(data, size);
  if (IsPng(data, size)) return PngSize(data, size);
  return std::nullopt;
}

ExifFields ReadExif(const std::uint8_t* data, std::size_t size, int width, int height) {
  ExifFields fields;
  // libexif takes an unsigned int length; EXIF sits at the start of a JPEG, so
  // a buffer beyond 4 GB cut to that length loses none of it.
  const unsigned int length = static_cast<unsigned int>(
      std::min<std::size_t>(size, std::numeric_limits<unsigned int>::max()));
  if (data == nullptr || length == 0) return fields;
  if (ExifData* exif = exif_data_new_from_data(data, length)) {
    fields.focal_length_px = ExifFocalLengthPx(exif, width, height);
    fields.camera_identity = ExifCameraIdentity(exif);
    exif_data_unref(exif);
  }
  return fields;
}

std::optional<double> ReadExifCaptureTime(const std::uint8_t* data, std::size_t size) {
  const unsigned int length = static_cast<unsigned int>(
      std::min<std::size_t>(size, std::numeric_limits<unsigned int>::max()));
  if (data == nullptr || length == 0) return std::nullopt;
  std::optional<double> time;
  if (ExifData* exif = exif_data_new_from_data(data, length)) {
    time = ExifCaptureTime(exif);
    exif_data_unref(exif);
  }
  return time;
}

DecodedImage DecodeImageBytes(const std::uint8_t* data, std::size_t size,
                              const DecodeOptions& options, int colour_long_side) {
  if (data == nullptr || size == 0) return Failure("empty image data (0 bytes)");
  if (size > options.max_file_bytes) {
    return Failure(std::to_string(size) + " bytes, above max_file_bytes (" +
                   std::to_string(options.max_file_bytes) + ")");
  }
  const bool jpeg = IsJpeg(data, size);
  const bool png = IsPng(data, size);
  if (jpeg && !HasJpegMarkers(data, size)) {
    return Failure("truncated JPEG: no end-of-image marker");
  }
  if (png && !HasPngMarkers(data, size)) {
    return Failure("truncated PNG: no IEND chunk");
  }
  // Only the formats whose headers are read here reach OpenCV: its other
  // decoders allocate whatever a header claims (a 19-byte PPM header claiming
  // 30000 x 30000 pixels: 2.7 GB) and one of them (DICOM, through GDCM)
  // aborts the process on a malformed file. Cameras write JPEG, TUM PNG.
  if (!jpeg && !png) {
    return Failure("neither JPEG nor PNG (" + std::to_string(size) +
                   " bytes); only those two are decoded");
  }
  const std::optional<ImageSize> claimed = ReadImageSize(data, size);
  if (!claimed) {
    return Failure(jpeg ? "JPEG without a readable frame header (SOF) before its data"
                        : "PNG without a readable IHDR chunk");
  }
  const double pixels = double(claimed->width) * double(claimed->height);
  if (pixels > options.max_image_pixels) {
    char message[160];
    std::snprintf(message, sizeof(message),
                  "the header claims %u x %u pixels (%.4g MP), above max_image_pixels "
                  "(%.4g MP); not decoded",
                  claimed->width, claimed->height, pixels / 1e6,
                  options.max_image_pixels / 1e6);
    return Failure(message);
  }
  // The largest DCT reduction whose long side keeps `colour_long_side`
  // pixels; libjpeg rounds each scaled side up.
  const std::uint32_t long_side = std::max(claimed->width, claimed->height);
  int reduction = 1;
  while (jpeg && colour_long_side > 0 && reduction < 8 &&
         (long_side + 2 * reduction - 1) / (2 * reduction) >= std::uint32_t(colour_long_side)) {
    reduction *= 2;
  }
  DecodedImage result;
  result.colour_reduction = reduction;
  try {
    const cv::Mat buffer(1, static_cast<int>(size), CV_8U,
                         const_cast<std::uint8_t*>(data));
    const int colour_flag = reduction == 8   ? cv::IMREAD_REDUCED_COLOR_8
                            : reduction == 4 ? cv::IMREAD_REDUCED_COLOR_4
                            : reduction == 2 ? cv::IMREAD_REDUCED_COLOR_2
                                             : cv::IMREAD_COLOR;
    result.image = cv::imdecode(buffer, colour_flag | cv::IMREAD_IGNORE_ORIENTATION);
    if (reduction == 1) {
      if (!result.image.empty()) cv::cvtColor(result.image, result.grey, cv::COLOR_BGR2GRAY);
    } else {
      result.grey = cv::imdecode(buffer, cv::IMREAD_GRAYSCALE | cv::IMREAD_IGNORE_ORIENTATION);
    }
  } catch (const cv::Exception& e) {
    return Failure(std::string("image decoder error: ") + e.what());
  }
  if (result.image.empty() || result.grey.empty()) {
    return Failure("not a decodable image (unknown format or corrupt data, " +
                   std::to_string(size) + " bytes)");
  }
  if (result.image.size() != DctReducedSize(result.grey.size(), reduction)) {
    return Failure("the JPEG decodes to different sizes in colour and in grey");
  }
  if (jpeg) {
    ExifFields exif = ReadExif(data, size, result.grey.cols, result.grey.rows);
    result.exif_focal_length_px = exif.focal_length_px;
    result.camera_identity = std::move(exif.camera_identity);
  }
  return result;
}

DecodedImage DecodeImageBytes(const std::vector<std::uint8_t>& bytes,
                              const DecodeOptions& options, int colour_long_side) {
  return DecodeImageBytes(bytes.data(), bytes.size(), options, colour_long_side);
}

std::optional<std::vector<std::uint8_t>> ReadImageFileBytes(const std::string& path,
                                                            std::uintmax_t max_bytes,
                                                            std::string* error) {
  const auto fail = [&](const std::string& why) {
    if (error != nullptr) *error = why;
    return std::nullopt;
  };
  std::ifstream file(path, std::ios::binary);
  if (!file) return fail("cannot open image file '" + path + "'");
  std::vector<std::uint8_t> bytes;
  char chunk[1 << 16];
  while (file.read(chunk, sizeof(chunk)) || file.gcount() > 0) {
    bytes.insert(bytes.end(), chunk, chunk + file.gcount());
    if (bytes.size() > max_bytes) {
      return fail("image file '" + path + "' is larger than max_file_bytes (" +
                  std::to_string(max_bytes) + ")");
    }
  }
  if (file.bad()) return fail("cannot read image file '" + path + "'");
  return bytes;
}

DecodedImage DecodeImageFile(const std::string& path, const DecodeOptions& options,
                             int colour_long_side) {
  std::string error;
  const std::optional<std::vector<std::uint8_t>> bytes =
      ReadImageFileBytes(path, options.max_file_bytes, &error);
  if (!bytes) return Failure(error);
  DecodedImage result = DecodeImageBytes(*bytes, options, colour_long_side);
  if (!result.ok()) result.error = "'" + path + "': " + result.error;
  return result;
}

bool HasImageExtension(const std::string& path) {
  static const char* kExtensions[] = {".jpg", ".jpeg", ".png", ".tif", ".tiff",
                                      ".bmp", ".pgm",  ".ppm"};
  std::string extension = std::filesystem::path(path).extension().string();
  std::transform(extension.begin(), extension.end(), extension.begin(),
                 [](unsigned char c) { return char(std::tolower(c)); });
  return std::find(std::begin(kExtensions), std::end(kExtensions), extension) !=
         std::end(kExtensions);
}

std::vector<std::string> ListImageFiles(const std::string& dir,
                                        std::vector<std::string>* skipped) {
  namespace fs = std::filesystem;
  std::error_code error;
  if (!fs::is_directory(dir, error)) {
    throw std::invalid_argument("image folder '" + dir + "' does not exist");
  }
  std::vector<std::string> files;
  const auto skip = [&](const fs::path& path, const std::error_code& why) {
    if (skipped != nullptr) skipped->push_back(path.string() + ": " + why.message());
  };
  fs::directory_iterator entries(dir, error);
  // The error_code forms throughout: one bad entry (a symbolic link loop, a
  // file without permission) must not end the listing of the others.
  for (; !error && entries != fs::directory_iterator(); entries.increment(error)) {
    const fs::directory_entry& entry = *entries;
    if (!HasImageExtension(entry.path().string())) continue;
    std::error_code entry_error;
    const bool regular = entry.is_regular_file(entry_error);
    if (entry_error) {
      skip(entry.path(), entry_error);
    } else if (regular) {
      files.push_back(entry.path().string());
    }
  }
  if (error) skip(dir, error);
  std::sort(files.begin(), files.end());
  return files;
}

}  // namespace flysfm
