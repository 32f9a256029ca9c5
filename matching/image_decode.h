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
  // 8-bit grey at the file's stored size, in its stored pixel grid (EXIF
  // orientation is ignored so that pixel coordinates agree with calibrations
  // made on the raw frames). Empty on failure.
  cv::Mat grey;
  // 8-bit BGR, the stored size divided by `colour_reduction` (rounded up).
  cv::Mat image;
  // 1, or 2, 4 or 8 when a JPEG's colour was decoded by DCT scaling.
  int colour_reduction = 1;
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

// Bounds on what one image may cost before it is decoded: the bytes come
// from outside (a camera, a folder anyone can write into).
struct DecodeOptions {
  // An image whose header claims more pixels is rejected before decoding: a
  // 1 KB JPEG may claim 60000 x 60000 pixels, 10 GB once decoded. 200 MP is
  // above any 12-45 MP body and generous for 100 MP medium format.
  double max_image_pixels = 200e6;
  // A larger file is not read: a 200 MP 8-bit RGB TIFF stored uncompressed
  // takes 600 MB, a camera JPEG of that size under 100 MB.
  std::uintmax_t max_file_bytes = std::uintmax_t(1) << 30;

  // False when an option is out of range; `error` then names it.
  bool Check(std::string* error = nullptr) const;
};

// The pixel size a JPEG's frame header (SOF) or a PNG's IHDR chunk claims,
// read without decoding. Other formats and headers that are missing or cut
// short give nullopt.
struct ImageSize {
  std::uint32_t width = 0;
  std::uint32_t height = 0;
};
std::optional<ImageSize> ReadImageSize(const std::uint8_t* data, std::size_t size);

// Completeness of encoded bytes, checked before anything is decoded: a file
// still being written or a download cut short lacks its closing marker.
// JPEG: start (FF D8) and end (FF D9) markers, zero padding after the end
// allowed (some cameras write it). PNG: signature and a final IEND chunk.
bool HasJpegMarkers(const std::uint8_t* data, std::size_t size);
bool HasPngMarkers(const std::uint8_t* data, std::size_t size);

// What the engine takes from EXIF; see DecodedImage for each field.
struct ExifFields {
  std::optional<double> focal_length_px;
  std::string camera_identity;
};

// Reads EXIF from a whole JPEG or from an APP1 payload alone (starting
// "Exif\0\0"), for an image of `width` x `height` pixels (focal lengths in
// pixels scale with the image). Bytes without readable EXIF give no fields.
ExifFields ReadExif(const std::uint8_t* data, std::size_t size, int width, int height);
// When the shot was taken, from EXIF DateTimeOriginal with its
// SubSecTimeOriginal digits when present: seconds from 1970-01-01 00:00 on
// the camera's own clock (EXIF gives no time zone without the optional
// OffsetTimeOriginal, which is not read, so times compare between cameras
// whose clocks were set alike). `data` as for ReadExif; the head of a JPEG
// holding its APP1 segment is enough. nullopt without the tag, or for a date
// a camera whose clock was never set writes ("0000:00:00 00:00:00").
std::optional<double> ReadExifCaptureTime(const std::uint8_t* data, std::size_t size);

// The size libjpeg's DCT scaling gives an image of `full` size reduced by
// `reduction` (2, 4 or 8; 1 leaves it): each side rounded up.
inline cv::Size DctReducedSize(const cv::Size& full, int reduction) {
  return {(full.width + reduction - 1) / reduction, (full.height + reduction - 1) / reduction};
}

// Decodes JPEG and PNG; other bytes are a failure (OpenCV's other decoders
// allocate what a hostile header claims, and its DICOM reader aborts on a
// malformed file). A JPEG must end with its EOI marker and a PNG with its
// IEND chunk: a truncated file is a failure even where the codec would
// return a partly grey image. A header claiming more than `max_image_pixels`
// is a failure before any decoding.
//
// With `colour_long_side` > 0 a JPEG's colour is decoded at the smallest
// size, 1/2, 1/4 or 1/8, whose long side keeps at least that many pixels
// (libjpeg's scaled IDCT, one pass), and its grey at full size from the
// luma alone: a full 24 MP colour decode costs two to three times the grey
// one and 72 MB, for colours that are read only at keypoints found on a
// 1 600-pixel copy. PNGs and small JPEGs are decoded once, in colour, and
// the grey converted from it.
DecodedImage DecodeImageBytes(const std::uint8_t* data, std::size_t size,
                              const DecodeOptions& options = {}, int colour_long_side = 0);
DecodedImage DecodeImageBytes(const std::vector<std::uint8_t>& bytes,
                              const DecodeOptions& options = {}, int colour_long_side = 0);

// The whole file, when it can be read and holds at most `max_bytes` (read
// up to one byte more, so a file still growing is caught too); otherwise
// nullopt, and `error` says why.
std::optional<std::vector<std::uint8_t>> ReadImageFileBytes(const std::string& path,
                                                            std::uintmax_t max_bytes,
                                                            std::string* error = nullptr);

// Reads the whole file, then as DecodeImageBytes. A file over
// `max_file_bytes` is a failure without being read.
DecodedImage DecodeImageFile(const std::string& path, const DecodeOptions& options = {},
                             int colour_long_side = 0);

// Whether the name ends in an image extension: jpg, jpeg, png, tif, tiff,
// bmp, pgm, ppm; any case.
bool HasImageExtension(const std::string& path);

// The image files (by HasImageExtension) directly inside `dir`, sorted by name. A missing folder is bad input:
// std::invalid_argument. An entry that cannot be examined (a symbolic link
// loop, no permission) is left out and, with `skipped`, reported there as
// "path: reason".
std::vector<std::string> ListImageFiles(const std::string& dir,
                                        std::vector<std::string>* skipped = nullptr);

}  // namespace flysfm
