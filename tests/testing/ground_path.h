#pragma once

// A long camera path over a textured ground: a survey flight in lawnmower
// strips, nadir-looking cameras, points scattered on gently rolling terrain.
// Each image sees a few hundred points and overlaps its strip neighbours and
// the adjacent strips, like the image blocks the engine grows one image at a
// time. Deterministic for a seed; scales to thousands of images.

#include <cstdint>
#include <vector>

#include "geometry/camera.h"
#include "tests/testing/synthetic.h"

namespace flysfm::testing {

struct GroundPathSceneOptions {
  int num_images = 100;
  int images_per_strip = 50;
  // Flight height over the mean ground and spacings, in scene units. With the
  // default camera (f = 500 px, 640 x 480) the footprint is 12.8 x 9.6, so
  // these give 84 % forward and 37 % side overlap.
  double altitude = 10.0;
  double image_spacing = 2.0;
  double strip_spacing = 6.0;
  // Points per square unit of ground (2.5: about 300 per image).
  double point_density = 2.5;
  // Amplitude of the terrain relief, so that depths vary across an image.
  double relief = 1.0;
  double max_tilt_deg = 3.0;
  // Observation noise, standard deviation in pixels.
  double noise_px = 0.0;
  Camera camera = Camera::FromFocal(CameraModelId::kSimplePinhole, 500, 640, 480);
  std::uint32_t seed = 0;
};

SyntheticScene MakeGroundPathScene(const GroundPathSceneOptions& options);

// For every image, the other images ranked by the number of points they share
// with it (ties by id), at most `max_neighbours`: a stand-in for retrieval's
// ranked top-N list.
std::vector<std::vector<int>> RankByCovisibility(const SyntheticScene& scene,
                                                 int max_neighbours);

}  // namespace flysfm::testing
