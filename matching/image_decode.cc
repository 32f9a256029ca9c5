#include "matching/image_decode.h"

#include <algorithm>
#include <cctype>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <stdexcept>

#include <opencv2/imgcodecs.hpp>

namespace flysfm {
namespace {

bool IsJpeg(const std::uint8_t* data, std::size_t size) {
  return size >= 3 && data[0] == 0xFF && data[1] == 0xD8 && data[2] == 0xFF;
}

bool IsPng(const std::uint8_t* data, std::size_t size) {
  static const std::uint8_t kSignature[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1A, '\n'};
  return size >= 8 && std::memcmp(data, kSignature, 8) == 0;
}

// Some writers pad after the EOI marker, so it is looked for near the end
// rather than exactly at it.
bool JpegHasEoi(const std::uint8_t* data, std::size_t size) {
  constexpr std::size_t kMaxTrailing = 4096;
  const std::size_t stop = size > kMaxTrailing ? size - kMaxTrailing : 1;
  for (std::size_t i = size - 1; i >= stop; --i) {
    if (data[i - 1] == 0xFF && data[i] == 0xD9) return true;
  }
  return false;
}

bool PngHasIend(const std::uint8_t* data, std::size_t size) {
  // The IEND chunk: length 0, type "IEND", CRC; always the last 12 bytes.
  return size >= 8 + 12 && std::memcmp(data + size - 8, "IEND", 4) == 0;
}

DecodedImage Failure(std::string message) {
  DecodedImage result;
  result.error = std::move(message);
  return result;
}

}  // namespace

DecodedImage DecodeImageBytes(const std::uint8_t* data, std::size_t size) {
  if (data == nullptr || size == 0) return Failure("empty image data (0 bytes)");
  if (IsJpeg(data, size) && !JpegHasEoi(data, size)) {
    return Failure("truncated JPEG: no end-of-image marker");
  }
  if (IsPng(data, size) && !PngHasIend(data, size)) {
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
