#pragma once

// Cheap completeness checks on encoded image bytes, made before anything is
// decoded: a file still being written or a download cut short lacks its
// closing marker.

#include <cstdint>
#include <filesystem>
#include <vector>

namespace flysfm {

// matching's HasJpegMarkers / HasPngMarkers on a whole buffer.
bool HasJpegMarkers(const std::vector<std::uint8_t>& bytes);
bool HasPngMarkers(const std::vector<std::uint8_t>& bytes);
// By the file's extension: JPEG and PNG by their markers; other formats have
// no end marker to check and pass when not empty.
bool LooksCompleteImage(const std::filesystem::path& name,
                        const std::vector<std::uint8_t>& bytes);
// The whole file's bytes; empty when it cannot be read or holds more than
// DecodeOptions::max_file_bytes.
std::vector<std::uint8_t> ReadFileBytes(const std::filesystem::path& path);

}  // namespace flysfm
