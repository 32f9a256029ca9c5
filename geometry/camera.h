#pragma once

#include <string>
#include <vector>

#include <Eigen/Core>

#include "geometry/camera_models.h"

namespace flysfm {

// A row's exposure time after the middle row's, as a fraction of a rolling
// shutter's readout time: -1/2 at the top edge, +1/2 at the bottom.
inline double RowTimeFraction(double row, int height) {
  return (row - 0.5 * height) / height;
}

// Intrinsics of one physical camera: a model from camera_models.h, its
// parameters in COLMAP's order, and the image size in pixels.
struct Camera {
  CameraModelId model_id = CameraModelId::kSimplePinhole;
  int width = 0;
  int height = 0;
  std::vector<double> params;
  // Rolling shutter: seconds from the exposure of the first row to that of
  // the last (0: a global shutter, or unknown). Estimated by the global
  // bundle adjustment of a video, where each frame's motion is known from its
  // neighbours in time (docs/bundle.md).
  double readout_time = 0;

  // Parses "MODEL p1,p2,..." (commas and/or spaces between numbers), e.g.
  // "FULL_OPENCV 517.3,516.5,318.6,255.3,0.2624,-0.9531,-0.0054,0.0026,
  // 1.1633,0,0,0". Throws std::invalid_argument naming what is wrong: an
  // unknown model (listing the known ones), a wrong parameter count (with the
  // expected names), a malformed or non-finite number.
  static Camera FromString(const std::string& text, int width, int height);
  // A pinhole-style camera of the given model with focal length `focal`, the
  // principal point at the image centre and zero distortion. Pixel centres
  // lie at integer coordinates (the top-left pixel's at (0, 0), as in OpenCV
  // and LSM), so the centre of a w x h image is ((w - 1) / 2, (h - 1) / 2).
  static Camera FromFocal(CameraModelId model_id, double focal, int width,
                          int height);

  // "MODEL p1,p2,..." with round-trip precision.
  std::string ToString() const;
  const char* ModelName() const;
  const char* ParamsInfo() const;
  int NumParams() const;
  int NumFocalParams() const;
  bool HasDistortion() const;

  double MeanFocalLength() const;
  // Every focal parameter (one, or fx and fy) set to `focal`.
  void SetFocalLength(double focal);
  // Converts a pixel threshold into the normalized image plane.
  double CamFromImgThreshold(double pixels) const;

  // Point in camera coordinates -> pixel.
  Eigen::Vector2d ImgFromCam(const Eigen::Vector3d& point_in_cam) const;
  // Where a point at `in_cam` in the pose's frame is when row `row` is read
  // out, the camera moving at `angular_velocity` and `linear_velocity` (its
  // own frame, per second): in_cam + tau (w x in_cam + v), tau the row's time
  // after the middle row's (RowTimeFraction * readout_time), to first order.
  Eigen::Vector3d InCamAtRow(const Eigen::Vector3d& in_cam, double row,
                             const Eigen::Vector3d& angular_velocity,
                             const Eigen::Vector3d& linear_velocity) const;
  // Pixel -> normalized image coordinates (x/z, y/z) of its viewing ray.
  Eigen::Vector2d CamFromImg(const Eigen::Vector2d& pixel) const;

  // True when the parameter count fits the model, every parameter is finite
  // and the focal lengths are positive.
  bool IsValid() const;
};

CameraModelId CameraModelIdFromName(const std::string& name);  // throws
std::string CameraModelName(CameraModelId model_id);
int CameraModelNumParams(CameraModelId model_id);

}  // namespace flysfm
