#pragma once

// A capture the program renders itself: a hand-held walk past the textured
// facet scene (synthetic_scene.h), each view encoded as PNG like a camera's
// file, with the exact pose of every shot. It lets a fresh machine run the
// whole pipeline with no data at hand (`flysfm demo`) and gives tests ground
// truth.

#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include "core/scene/frame.h"
#include "geometry/camera.h"
#include "geometry/rigid3d.h"

namespace flysfm {

struct SyntheticCaptureOptions {
  int num_views = 24;
  // The walk: `path_length` metres along x at about 5 m from the back wall,
  // with up to 0.2 m of jitter in height and distance and 0.3 m in where each
  // shot aims.
  double path_length = 3.0;
  // Sub-pixel rays per pixel side (anti-aliasing, the sensor's area).
  int supersampling = 2;
  std::uint32_t seed = 1;
  // Intrinsics of the rendering camera (known to the engine in the demo).
  Camera camera = Camera::FromString("PINHOLE 500,500,320,240", 640, 480);

  bool Check() const;
};

struct SyntheticCapture {
  Camera camera;
  // frames[i] ("view<100+i>.png", PNG bytes) was shot from cams_from_world[i].
  std::vector<Frame> frames;
  std::vector<Rigid3d> cams_from_world;

  // Each frame's camera centre by frame name: the ground truth of
  // CompareCentersByName.
  std::map<std::string, Eigen::Vector3d> CameraCentres() const;
};

// Throws std::invalid_argument for invalid options.
SyntheticCapture MakeSyntheticCapture(const SyntheticCaptureOptions& options);

}  // namespace flysfm
