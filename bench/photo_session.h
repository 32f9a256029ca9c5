#pragma once

// The rendered photo session of bench_photos, bench_refine and bench_agents:
// a building (16 m x 12 m, 8 m high, two bays, a textured ground) and
// photographers' paths around it, rendered by io/synthetic as JPEGs, with
// the exact pose of every shot.

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "geometry/camera.h"
#include "geometry/rigid3d.h"

namespace flysfm {

struct Shot {
  std::string name;  // photo_NNNN.jpg in the order of the path, or the ring stop's
  Rigid3d cam_from_world;
  double distance_to_building;  // to the footprint, metres
};

// One plane of the scene: the parallelogram origin + a u + b v, a and b in
// [0, 1], textured at `texels_per_metre`. World z is up, the ground z = 0.
struct BuildingFacet {
  Eigen::Vector3d origin;
  Eigen::Vector3d axis_u;
  Eigen::Vector3d axis_v;
  double texels_per_metre = 0;
};
// The scene's facets, in the order their textures are seeded: the four
// walls (south, east, north, west; the building has no roof), the two bays
// (front, sides and roof each), the ground.
std::vector<BuildingFacet> BuildingFacets();

// The session's camera as Camera::FromString reads it: a 3:2 sensor `width`
// pixels wide behind a 30 mm-equivalent lens (f = 30/36 of the width), the
// principal point at the image centre.
std::string PhotoSessionCamera(int width);

// The photographer's path: loops at 1.6 m and 10 m, 1.6 m and 16 m, 4.5 m (a
// raised position) and 12 m, the first loop again (revisits), then 3 m high
// at 8-20 m; steps of 1-3 m, each shot aimed at the nearest part of the
// building with the hand's jitter in distance, height, yaw, pitch and roll.
// The first `num_photos` shots of it.
std::vector<Shot> MakePhotoSession(int num_photos, std::uint32_t seed);

// Where a photographer stands on a circle about the building's centre.
struct RingStop {
  std::string name;   // the shot's file name
  double angle_deg;   // counter-clockwise from +x (east); -90 is south
  double radius_m;    // from the building's centre, on the ground
  double height_m;    // of the camera
};

// One shot per stop, aimed at the building's centre at 3.5 m with the
// hand's jitter (up to 0.3 m along the radius, 0.1 m in height, 5 deg of
// yaw, 3 deg of pitch, 2 deg of roll), seeded: a ring of shots around the
// building, whichever part of it each photographer walks.
std::vector<Shot> MakeRingShots(const std::vector<RingStop>& stops, std::uint32_t seed);

// Makes `dir` hold renders of this scene version, seed, camera,
// supersampling and `plan` only (`plan` names the shot plan and its
// parameters when it is not bench_photos' path): JPEGs rendered otherwise
// (its manifest says) are removed, so that a kept folder is reused only when
// it matches.
void PrepareRenderFolder(const std::filesystem::path& dir, std::uint32_t seed,
                         const Camera& camera, int supersampling,
                         const std::string& plan = "");

// Renders the shots missing from `dir` as JPEGs (quality 92; OpenCV writes
// JFIF, no EXIF, so an uncalibrated engine must guess the focal length) on
// `num_threads` threads. Returns the render times (ms) of the photos
// rendered now.
std::vector<double> RenderPhotoSession(const std::vector<Shot>& shots, const Camera& camera,
                                       std::uint32_t seed, int supersampling,
                                       const std::filesystem::path& dir, int num_threads);

}  // namespace flysfm
