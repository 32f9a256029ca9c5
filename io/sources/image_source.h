#pragma once

// Where images come from. Every source (a folder, a TUM sequence, a watched
// folder, a CAMFI transmitter, a rendered scene) yields the same Frame (core/frame.h),
// so the engine loop never knows where an image came from.

#include <cstdint>
#include <filesystem>
#include <optional>
#include <vector>

#include "core/frame.h"

namespace flysfm {

class ImageSource {
 public:
  virtual ~ImageSource() = default;
  // The next frame, blocking until it arrives; nullopt once the source is
  // exhausted or stopped.
  virtual std::optional<Frame> Next() = 0;
};

// Image files (matching's ListImageFiles: jpg, jpeg, png, tif, tiff, bmp,
// pgm, ppm; any case) directly in `dir`, sorted by name. Throws std::invalid_argument for a missing folder or one without
// images.
std::vector<Frame> ListImageFolder(const std::filesystem::path& dir);
// The frames of a TUM RGB-D sequence folder in rgb.txt order, named by their
// path in rgb.txt ("rgb/<timestamp>.png"), timestamped from it. Throws
// std::invalid_argument naming the line of a malformed rgb.txt.
std::vector<Frame> ListTumSequence(const std::filesystem::path& dir);
// A TUM sequence when `path` holds rgb.txt, else an image folder.
std::vector<Frame> ListBatchInput(const std::filesystem::path& path);
// A reproducible random order: any capture order must work.
void ShuffleFrames(std::vector<Frame>* frames, std::uint32_t seed);

// Hands out a list of frames, one every `interval_seconds` (0: at once), each
// stamped with its arrival time, like a camera shooting at that pace.
class FrameListSource : public ImageSource {
 public:
  explicit FrameListSource(std::vector<Frame> frames,
                           double interval_seconds = 0.0);
  std::optional<Frame> Next() override;

 private:
  std::vector<Frame> frames_;
  double interval_seconds_;
  std::size_t next_ = 0;
  std::chrono::steady_clock::time_point start_;
};

}  // namespace flysfm
