#include "io/sources/image_source.h"

#include <algorithm>
#include <fstream>
#include <random>
#include <sstream>
#include <stdexcept>

#include "io/formats/data_lines.h"
#include "matching/image_decode.h"

namespace flysfm {
namespace fs = std::filesystem;

std::vector<Frame> ListImageFolder(const fs::path& dir, std::vector<std::string>* skipped) {
  const std::vector<std::string> paths = ListImageFiles(dir.string(), skipped);
  if (paths.empty()) {
    throw std::invalid_argument("no images (jpg, jpeg, png, tif, bmp, pgm, ppm) in " +
                                dir.string());
  }
  std::vector<Frame> frames;
  for (const std::string& path : paths) {
    Frame frame;
    frame.path = path;
    frame.name = frame.path.filename().string();
    frame.timestamp = double(frames.size());
    frames.push_back(std::move(frame));
  }
  return frames;
}

std::vector<Frame> ListTumSequence(const fs::path& dir) {
  const fs::path list = dir / "rgb.txt";
  std::ifstream in(list);
  if (!in) throw std::invalid_argument("cannot read " + list.string());
  std::vector<Frame> frames;
  ForEachDataLine(in, [&](const std::string& line, int number) {
    std::istringstream fields(line);
    Frame frame;
    if (!(fields >> frame.timestamp >> frame.name)) {
      throw std::invalid_argument(list.string() + ":" + std::to_string(number) +
                                  ": expected 'timestamp filename'");
    }
    frame.path = dir / frame.name;
    frames.push_back(std::move(frame));
  });
  if (frames.empty()) throw std::invalid_argument(list.string() + " lists no frames");
  return frames;
}

std::vector<Frame> ListBatchInput(const fs::path& path, std::vector<std::string>* skipped) {
  return fs::exists(path / "rgb.txt") ? ListTumSequence(path) : ListImageFolder(path, skipped);
}

std::optional<double> ReadCaptureTime(const Frame& frame) {
  if (!frame.bytes.empty()) return ReadExifCaptureTime(frame.bytes.data(), frame.bytes.size());
  // An APP1 segment is at most 64 KiB, after SOI and perhaps a JFIF APP0.
  std::vector<std::uint8_t> head(128 * 1024);
  std::ifstream file(frame.path, std::ios::binary);
  if (!file) return std::nullopt;
  file.read(reinterpret_cast<char*>(head.data()), std::streamsize(head.size()));
  head.resize(std::size_t(file.gcount()));
  return ReadExifCaptureTime(head.data(), head.size());
}

void ShuffleFrames(std::vector<Frame>* frames, std::uint32_t seed) {
  std::mt19937 rng(seed);
  std::shuffle(frames->begin(), frames->end(), rng);
}

FrameListSource::FrameListSource(std::vector<Frame> frames,
                                 double interval_seconds)
    : frames_(std::move(frames)), interval_seconds_(interval_seconds) {
  if (!(interval_seconds >= 0)) {
    throw std::invalid_argument("the interval must be >= 0 seconds");
  }
}

void FrameListSource::Stop() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stopped_ = true;
  }
  stopped_changed_.notify_all();
}

std::optional<Frame> FrameListSource::Next() {
  std::unique_lock<std::mutex> lock(mutex_);
  if (next_ >= frames_.size()) return std::nullopt;
  // Frame i arrives i intervals after the first, whatever the engine's pace.
  if (next_ > 0) {
    stopped_changed_.wait_until(
        lock,
        start_ + std::chrono::duration_cast<std::chrono::steady_clock::duration>(
                     std::chrono::duration<double>(interval_seconds_ * next_)),
        [this] { return stopped_; });
  }
  if (stopped_) return std::nullopt;
  Frame frame = std::move(frames_[next_]);
  frame.arrival = std::chrono::steady_clock::now();
  if (next_++ == 0) start_ = frame.arrival;
  return frame;
}

}  // namespace flysfm
