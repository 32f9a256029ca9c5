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
  // Set once the image is registered, in the frame of its sub-model.
  std::optional<Rigid3d> cam_from_world;
  model_t model_id = kInvalidModelId;
  // When the image was taken, in seconds, if its source knows (a video's
  // frame times); the motion a rolling shutter needs comes from it.
  std::optional<double> capture_time;
  // The camera's motion while a rolling shutter read this image out, in its
  // own frame per second (Camera::InCamAtRow), as the last bundle adjustment
  // that modelled it left it; zero for a still camera and for every photo.
  Eigen::Vector3d angular_velocity = Eigen::Vector3d::Zero();
  Eigen::Vector3d linear_velocity = Eigen::Vector3d::Zero();
  std::vector<Point2D> points2D;
  // How many of points2D observe a 3D point, kept by Reconstruction.
  int num_points3D = 0;

  bool IsRegistered() const { return cam_from_world.has_value(); }
};

}  // namespace flysfm
