#pragma once

#include <filesystem>
#include <unordered_map>

#include "core/scene/reconstruction.h"
#include "quality/coverage.h"
#include "quality/measures.h"

namespace flysfm {

// What an undefined `sigma` (a point seen once, or along parallel rays) is
// written as: the largest finite float, so that every PLY reader takes it and
// a colour ramp puts it with the worst points.
constexpr float kPlyUndefinedSigma = 3.402823466e38f;

// The 3D points as a coloured binary little-endian PLY (x, y, z as double;
// red, green, blue as uchar), written atomically. With `quality` (a
// QualityTracker's Points()), each vertex also carries `int views`,
// `float max_angle_deg`, `float error_px` and `float sigma` (the largest
// standard deviation of its position, model units; kPlyUndefinedSigma when
// undefined); a point missing from it gets 0, 0, 0 and kPlyUndefinedSigma.
void WritePly(const Reconstruction& reconstruction, const std::filesystem::path& path,
              const std::unordered_map<point3D_t, PointQuality>* quality = nullptr);

// The coverage surface (quality/coverage.h) as a binary little-endian PLY,
// written atomically: three float vertices per face (faces share none), and
// per face its corners, its colour (FaceClassColour: green well covered,
// orange too narrow an angle, red too few views, grey an underside,
// grey-blue out of reach), `int views`, `float max_angle_deg`, `float gsd`
// (model units per pixel) and `uchar coverage_class` (0 well covered, 1
// narrow angle, 2 few views, 3 underside, 4 out of reach). MeshLab and CloudCompare show it coloured as it is.
void WriteSurfacePly(const Coverage& coverage, const std::filesystem::path& path);

}  // namespace flysfm
