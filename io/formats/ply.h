#pragma once

#include <filesystem>

#include "core/scene/reconstruction.h"

namespace flysfm {

// The 3D points as a coloured binary PLY (x, y, z as double; red, green, blue
// as uchar), written atomically.
void WritePly(const Reconstruction& reconstruction, const std::filesystem::path& path);

}  // namespace flysfm
