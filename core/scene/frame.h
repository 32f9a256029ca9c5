#pragma once

#include <chrono>
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

namespace flysfm {

// One fly-in image as a source hands it to the engine: encoded, not yet
// decoded, so that decoding is timed and bad bytes are rejected in one place.
struct Frame {
  // The image's name in the model and the outputs (unique within a run).
  std::string name;
  // Either a file holding the encoded image or the encoded bytes themselves.
  std::filesystem::path path;
  std::vector<std::uint8_t> bytes;
  // Capture time in seconds when the source knows it (TUM), else the index.
  double timestamp = 0;
  // When the image reached us; the live delay is measured from here.
  std::chrono::steady_clock::time_point arrival;
  // The tag of the photographer's source it came from when several sources
  // feed one run (io/sources/merged_source.h); empty for a single source.
  // The engine carries it to nothing: the run loop reports it.
  std::string source;
};

}  // namespace flysfm
