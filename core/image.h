#pragma once

#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "geometry/types.h"
#include "geometry/rigid3d.h"

namespace flysfm {

// A keypoint of an image and the 3D point it observes, if any.
struct Point2D {
  Eigen::Vector2d xy = Eigen::Vector2d::Zero();  // pixel, distorted
  point3D_t point3D_id = kInvalidPoint3DId;

  bool HasPoint3D() const { return point3D_id != kInvalidPoint3DId; }
};

struct Image {
  image_t image_id = kInvalidImageId;
  camera_t camera_id = kInvalidCameraId;
  std::string name;
  // Set once the image is registered.
  std::optional<Rigid3d> cam_from_world;
  std::vector<Point2D> points2D;
  // How many of points2D observe a 3D point, kept by Reconstruction.
  int num_points3D = 0;

  bool IsRegistered() const { return cam_from_world.has_value(); }
};

}  // namespace flysfm
