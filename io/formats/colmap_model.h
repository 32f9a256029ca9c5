#pragma once

// The model in COLMAP's sparse format, text (cameras.txt, images.txt,
// points3D.txt) and binary (.bin), so COLMAP and the tools that read its
// format open our results. Only registered images are written, as COLMAP does.
// Pixel coordinates (keypoints, principal point) are converted to COLMAP's
// convention, the centre of the top-left pixel at (0.5, 0.5), on writing and
// back to ours, (0, 0) as in OpenCV, on reading.

#include <filesystem>

#include "core/scene/reconstruction.h"

namespace flysfm {

// Writes both formats into `dir` (created if needed), each file atomically.
void WriteColmapModel(const Reconstruction& reconstruction,
                      const std::filesystem::path& dir);
void WriteColmapText(const Reconstruction& reconstruction,
                     const std::filesystem::path& dir);
void WriteColmapBinary(const Reconstruction& reconstruction,
                       const std::filesystem::path& dir);

// Reads a model written by us or by COLMAP: binary when cameras.bin exists,
// else text. Throws std::runtime_error naming the file and line/record on
// malformed input.
Reconstruction ReadColmapModel(const std::filesystem::path& dir);
Reconstruction ReadColmapText(const std::filesystem::path& dir);
Reconstruction ReadColmapBinary(const std::filesystem::path& dir);

}  // namespace flysfm
