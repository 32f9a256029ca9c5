#pragma once

// Decoding of image files and in-memory byte buffers (live capture delivers
// bytes). Bad bytes are a reported failure, never an exception or a crash:
// the engine counts them as rejections and carries on.

#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

namespace flysfm {

struct DecodedImage {
  // 8-bit BGR, in the file's stored pixel grid (EXIF orientation is ignored so
  // that pixel coordinates agree with calibrations made on the raw frames).
  // Empty on failure.
  cv::Mat image;
  // Why decoding failed; empty on success.
  std::string error;
  // The focal length in pixels from a JPEG's EXIF, when it says enough:
  // FocalLengthIn35mmFilm (scaled from the 36 x 24 mm film's diagonal to the
  // image's), else FocalLength with FocalPlaneXResolution; none when it
  // would be a 35 mm equivalent outside 8-2 000 mm.
  std::optional<double> exif_focal_length_px;
  // The camera body and lens as the EXIF names them (Make, Model,
  // BodySerialNumber, LensModel) and the focal length in mm (a zoom at
  // another setting has other intrinsics): images with the same identity
  // and size share intrinsics. Printable ASCII, bounded; empty without EXIF.
  std::string camera_identity;

  bool ok() const { return error.empty(); }
};

// Completeness of encoded bytes, checked before anything is decoded: a file
// still being written or a download cut short lacks its closing marker.
// JPEG: start (FF D8) and end (FF D9) markers, zero padding after the end
// allowed (some cameras write it). PNG: signature and a final IEND chunk.
bool HasJpegMarkers(const std::uint8_t* data, std::size_t size);
bool HasPngMarkers(const std::uint8_t* data, std::size_t size);

// Decodes JPEG, PNG and the other formats OpenCV reads. A JPEG must end with
// its EOI marker and a PNG with its IEND chunk: a truncated file is a failure
// even where the codec would return a partly grey image.
DecodedImage DecodeImageBytes(const std::uint8_t* data, std::size_t size);
DecodedImage DecodeImageBytes(const std::vector<std::uint8_t>& bytes);

// Reads the whole file, then as DecodeImageBytes.
DecodedImage DecodeImageFile(const std::string& path);

// The image files (by extension: jpg, jpeg, png, tif, tiff, bmp, pgm, ppm; any
// case) directly inside `dir`, sorted by name. A missing folder is bad input:
// std::invalid_argument.
std::vector<std::string> ListImageFiles(const std::string& dir);

}  // namespace flysfm
