#pragma once

// Where images come from. Every source (a folder, a TUM sequence, a watched
// folder, a CAMFI transmitter, a rendered scene) yields the same Frame (core/frame.h),
// so the engine loop never knows where an image came from.

#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <filesystem>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "core/scene/frame.h"

namespace flysfm {

class ImageSource {
 public:
  virtual ~ImageSource() = default;
  // The next frame, blocking until it arrives; nullopt once the source is
  // exhausted or stopped.
  virtual std::optional<Frame> Next() = 0;
  // Makes a blocked or later Next() return soon: what was already received
  // may still be handed out, then nullopt. Thread-safe. A source whose
  // Next() never waits needs nothing here.
  virtual void Stop() {}
};

// Image files (matching's ListImageFiles: jpg, jpeg, png, tif, tiff, bmp,
// pgm, ppm; any case) directly in `dir`, sorted by name. Throws
// std::invalid_argument for a missing folder or one without images. Entries
// that cannot be examined (a symbolic link loop) are left out and, with
// `skipped`, reported there as "path: reason".
std::vector<Frame> ListImageFolder(const std::filesystem::path& dir,
                                   std::vector<std::string>* skipped = nullptr);
// The frames of a TUM RGB-D sequence folder in rgb.txt order, named by their
// path in rgb.txt ("rgb/<timestamp>.png"), timestamped from it. Throws
// std::invalid_argument naming the line of a malformed rgb.txt.
std::vector<Frame> ListTumSequence(const std::filesystem::path& dir);
// A TUM sequence when `path` holds rgb.txt, else an image folder.
std::vector<Frame> ListBatchInput(const std::filesystem::path& path,
                                  std::vector<std::string>* skipped = nullptr);
// When the frame's shot was taken, from its EXIF (ReadExifCaptureTime: the
// camera's clock, in seconds), read from its bytes or from the head of its
// file (EXIF sits in the first 64 KiB of a JPEG); nullopt without one or
// when the file cannot be read.
std::optional<double> ReadCaptureTime(const Frame& frame);
// A reproducible random order: any capture order must work.
void ShuffleFrames(std::vector<Frame>* frames, std::uint32_t seed);

// Hands out a list of frames, one every `interval_seconds` (0: at once), each
// stamped with its arrival time, like a camera shooting at that pace.
class FrameListSource : public ImageSource {
 public:
  explicit FrameListSource(std::vector<Frame> frames,
                           double interval_seconds = 0.0);
  std::optional<Frame> Next() override;
  // Ends the list, waking a Next() waiting for the next interval.
  void Stop() override;

 private:
  std::vector<Frame> frames_;
  double interval_seconds_;
  std::size_t next_ = 0;
  std::chrono::steady_clock::time_point start_;  // the first frame's arrival
  std::mutex mutex_;
  std::condition_variable stopped_changed_;
  bool stopped_ = false;
};

// Ends after the first `max_images` frames of `source` (negative: never),
// for scripted runs. Not thread-safe but for Stop(), as every source.
class LimitedSource : public ImageSource {
 public:
  LimitedSource(ImageSource* source, int max_images) : source_(source), left_(max_images) {}
  std::optional<Frame> Next() override {
    if (left_ == 0) return std::nullopt;
    if (left_ > 0) --left_;
    return source_->Next();
  }
  void Stop() override { source_->Stop(); }

 private:
  ImageSource* source_;
  int left_;
};

}  // namespace flysfm
