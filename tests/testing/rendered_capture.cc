#include "tests/testing/rendered_capture.h"

#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <sstream>

namespace flysfm::testing {
namespace {

namespace fs = std::filesystem;

constexpr char kMagic[8] = {'f', 'l', 'y', 'c', 'a', 'p', '0', '1'};

std::string Key(const SyntheticCaptureOptions& options) {
  std::ostringstream text;
  text.precision(17);
  text << FLYSFM_RENDERER_HASH << ' ' << options.num_views << ' ' << options.path_length << ' '
       << options.supersampling << ' ' << options.seed << ' ' << int(options.camera.model_id)
       << ' ' << options.camera.width << ' ' << options.camera.height << ' '
       << options.camera.readout_time;
  for (const double param : options.camera.params) text << ' ' << param;
  return text.str();
}

fs::path CacheFile(const std::string& key) {
  const char* dir = std::getenv("FLYSFM_TEST_CACHE");
  std::ostringstream name;
  name << std::hex << std::hash<std::string>()(key) << ".capture";
  return fs::path(dir != nullptr ? dir : FLYSFM_TEST_CACHE_DIR) / name.str();
}

template <typename T>
void Put(std::ostream& out, const T& value) {
  out.write(reinterpret_cast<const char*>(&value), sizeof(T));
}

template <typename T>
bool Get(std::istream& in, T* value) {
  return bool(in.read(reinterpret_cast<char*>(value), sizeof(T)));
}

void PutString(std::ostream& out, const std::string& text) {
  Put(out, std::uint64_t(text.size()));
  out.write(text.data(), std::streamsize(text.size()));
}

bool GetString(std::istream& in, std::string* text) {
  std::uint64_t size = 0;
  if (!Get(in, &size) || size > (1u << 30)) return false;
  text->resize(size);
  return bool(in.read(text->data(), std::streamsize(size)));
}

void Write(const std::string& key, const SyntheticCapture& capture, std::ostream& out) {
  out.write(kMagic, sizeof(kMagic));
  PutString(out, key);
  Put(out, std::uint64_t(capture.frames.size()));
  for (std::size_t i = 0; i < capture.frames.size(); ++i) {
    const Frame& frame = capture.frames[i];
    PutString(out, frame.name);
    Put(out, frame.timestamp);
    PutString(out, std::string(frame.bytes.begin(), frame.bytes.end()));
    const Rigid3d& pose = capture.cams_from_world[i];
    for (const double value : {pose.rotation.w(), pose.rotation.x(), pose.rotation.y(),
                               pose.rotation.z(), pose.translation.x(), pose.translation.y(),
                               pose.translation.z()}) {
      Put(out, value);
    }
  }
}

// The capture stored under `key`; false when the file is not one.
bool Read(const std::string& key, std::istream& in, SyntheticCapture* capture) {
  char magic[sizeof(kMagic)];
  std::string stored_key;
  std::uint64_t num_frames = 0;
  if (!in.read(magic, sizeof(magic)) || !std::equal(magic, magic + sizeof(magic), kMagic) ||
      !GetString(in, &stored_key) || stored_key != key || !Get(in, &num_frames)) {
    return false;
  }
  for (std::uint64_t i = 0; i < num_frames; ++i) {
    Frame frame;
    std::string bytes;
    double pose[7];
    if (!GetString(in, &frame.name) || !Get(in, &frame.timestamp) || !GetString(in, &bytes)) {
      return false;
    }
    for (double& value : pose) {
      if (!Get(in, &value)) return false;
    }
    frame.bytes.assign(bytes.begin(), bytes.end());
    capture->frames.push_back(std::move(frame));
    // Set as stored: Rigid3d's constructor would normalise the rotation
    // again, and the cached capture must be the rendered one bit for bit.
    Rigid3d cam_from_world;
    cam_from_world.rotation = Eigen::Quaterniond(pose[0], pose[1], pose[2], pose[3]);
    cam_from_world.translation = Eigen::Vector3d(pose[4], pose[5], pose[6]);
    capture->cams_from_world.push_back(cam_from_world);
  }
  return true;
}

}  // namespace

SyntheticCapture RenderedCapture(const SyntheticCaptureOptions& options) {
  const std::string key = Key(options);
  const fs::path file = CacheFile(key);
  {
    SyntheticCapture cached;
    cached.camera = options.camera;
    std::ifstream in(file, std::ios::binary);
    if (in && Read(key, in, &cached)) return cached;
  }
  SyntheticCapture capture = MakeSyntheticCapture(options);
  // Written whole under a name of this process's, then renamed: a process
  // reading it at the same time sees the whole file or none.
  std::error_code error;
  fs::create_directories(file.parent_path(), error);
  const fs::path temporary = file.string() + "." + std::to_string(::getpid());
  {
    std::ofstream out(temporary, std::ios::binary | std::ios::trunc);
    Write(key, capture, out);
    if (!out.flush()) {
      fs::remove(temporary, error);
      return capture;
    }
  }
  fs::rename(temporary, file, error);
  if (error) fs::remove(temporary, error);
  return capture;
}

}  // namespace flysfm::testing
