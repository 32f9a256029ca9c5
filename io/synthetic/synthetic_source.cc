#include "io/synthetic/synthetic_source.h"

#include <random>
#include <stdexcept>
#include <string>

#include <opencv2/imgcodecs.hpp>

#include "io/synthetic/synthetic_scene.h"

namespace flysfm {

bool SyntheticCaptureOptions::Check() const {
  return num_views >= 2 && path_length > 0 && supersampling >= 1 && camera.IsValid() &&
         camera.width > 0 && camera.height > 0;
}

SyntheticCapture MakeSyntheticCapture(const SyntheticCaptureOptions& options) {
  if (!options.Check()) throw std::invalid_argument("invalid synthetic capture options");
  const TexturedScene scene = MakeFacetScene(options.seed);
  std::mt19937 rng(options.seed);
  std::uniform_real_distribution<double> jitter(-1.0, 1.0);
  SyntheticCapture capture;
  capture.camera = options.camera;
  for (int i = 0; i < options.num_views; ++i) {
    const double s = double(i) / (options.num_views - 1) - 0.5;
    const Eigen::Vector3d center(options.path_length * s, 0.2 * jitter(rng),
                                 -5.0 + 0.2 * jitter(rng));
    const Eigen::Vector3d target(0.3 * jitter(rng), 0.2 * jitter(rng), 1.0);
    const Eigen::Vector3d forward = (target - center).normalized();
    const Eigen::Vector3d right = Eigen::Vector3d::UnitY().cross(forward).normalized();
    Eigen::Matrix3d world_from_cam;
    world_from_cam << right, forward.cross(right), forward;
    const Rigid3d cam_from_world(Eigen::Matrix3d(world_from_cam.transpose()),
                                 -(world_from_cam.transpose() * center));
    const RenderedView view =
        Render(scene, options.camera, cam_from_world, options.supersampling);
    Frame frame;
    frame.name = "view" + std::to_string(100 + i) + ".png";
    frame.timestamp = i;
    cv::imencode(".png", view.image, frame.bytes);
    capture.frames.push_back(std::move(frame));
    capture.cams_from_world.push_back(cam_from_world);
  }
  return capture;
}

std::map<std::string, Eigen::Vector3d> SyntheticCapture::CameraCentres() const {
  std::map<std::string, Eigen::Vector3d> centres;
  for (std::size_t i = 0; i < frames.size(); ++i) {
    centres[frames[i].name] = ProjectionCenter(cams_from_world[i]);
  }
  return centres;
}

}  // namespace flysfm
