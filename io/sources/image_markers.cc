#include "io/sources/image_markers.h"

#include <algorithm>
#include <cctype>
#include <string>

#include "matching/image_decode.h"

namespace flysfm {

bool HasJpegMarkers(const std::vector<std::uint8_t>& bytes) {
  return HasJpegMarkers(bytes.data(), bytes.size());
}

bool HasPngMarkers(const std::vector<std::uint8_t>& bytes) {
  return HasPngMarkers(bytes.data(), bytes.size());
}

bool LooksCompleteImage(const std::filesystem::path& name,
                        const std::vector<std::uint8_t>& bytes) {
  std::string extension = name.extension().string();
  std::transform(extension.begin(), extension.end(), extension.begin(),
                 [](unsigned char c) { return char(std::tolower(c)); });
  if (extension == ".jpg" || extension == ".jpeg") return HasJpegMarkers(bytes);
  if (extension == ".png") return HasPngMarkers(bytes);
  return !bytes.empty();
}

std::vector<std::uint8_t> ReadFileBytes(const std::filesystem::path& path) {
  return ReadImageFileBytes(path.string(), DecodeOptions().max_file_bytes)
      .value_or(std::vector<std::uint8_t>());
}

}  // namespace flysfm
