#include "geometry/camera.h"

#include <cmath>
#include <iomanip>
#include <limits>
#include <sstream>
#include <stdexcept>

#include <Eigen/Geometry>

namespace flysfm {
namespace {

constexpr CameraModelId kAllModels[] = {
    CameraModelId::kSimplePinhole, CameraModelId::kPinhole,
    CameraModelId::kSimpleRadial,  CameraModelId::kRadial,
    CameraModelId::kOpenCV,        CameraModelId::kFullOpenCV};

std::string KnownModelNames() {
  std::string names;
  for (const CameraModelId id : kAllModels) {
    if (!names.empty()) names += ", ";
    names += CameraModelName(id);
  }
  return names;
}

}  // namespace

CameraModelId CameraModelIdFromName(const std::string& name) {
  for (const CameraModelId id : kAllModels) {
    if (CameraModelName(id) == name) return id;
  }
  throw std::invalid_argument("unknown camera model '" + name +
                              "' (known: " + KnownModelNames() + ")");
}

std::string CameraModelName(CameraModelId model_id) {
  return VisitCameraModel(model_id, [](auto model) {
    return std::string(decltype(model)::kName);
  });
}

int CameraModelNumParams(CameraModelId model_id) {
  return VisitCameraModel(model_id,
                          [](auto model) { return decltype(model)::kNumParams; });
}

Camera Camera::FromString(const std::string& text, int width, int height) {
  std::istringstream stream(text);
  std::string name;
  stream >> name;
  if (name.empty()) throw std::invalid_argument("empty camera specification");
  Camera camera;
  camera.model_id = CameraModelIdFromName(name);
  camera.width = width;
  camera.height = height;
  std::string rest;
  std::getline(stream, rest);
  for (char& c : rest) {
    if (c == ',') c = ' ';
  }
  std::istringstream numbers(rest);
  std::string token;
  while (numbers >> token) {
    std::size_t used = 0;
    double value = 0;
    try {
      value = std::stod(token, &used);
    } catch (const std::exception&) {
      used = 0;
    }
    if (used != token.size() || !std::isfinite(value)) {
      throw std::invalid_argument("camera parameter '" + token +
                                  "' is not a finite number");
    }
    camera.params.push_back(value);
  }
  if (static_cast<int>(camera.params.size()) != camera.NumParams()) {
    throw std::invalid_argument(
        name + " takes " + std::to_string(camera.NumParams()) +
        " parameters (" + camera.ParamsInfo() + "), got " +
        std::to_string(camera.params.size()));
  }
  if (!camera.IsValid()) {
    throw std::invalid_argument("camera '" + text +
                                "' has a non-positive focal length");
  }
  return camera;
}

Camera Camera::FromFocal(CameraModelId model_id, double focal, int width,
                         int height) {
  Camera camera;
  camera.model_id = model_id;
  camera.width = width;
  camera.height = height;
  camera.params.assign(camera.NumParams(), 0.0);
  camera.SetFocalLength(focal);
  const int num_focal = camera.NumFocalParams();
  camera.params[num_focal] = 0.5 * (width - 1);
  camera.params[num_focal + 1] = 0.5 * (height - 1);
  return camera;
}

std::string Camera::ToString() const {
  std::ostringstream out;
  out << ModelName() << ' '
      << std::setprecision(std::numeric_limits<double>::max_digits10);
  for (std::size_t i = 0; i < params.size(); ++i) {
    out << (i ? "," : "") << params[i];
  }
  return out.str();
}

const char* Camera::ModelName() const {
  return VisitCameraModel(model_id,
                          [](auto model) { return decltype(model)::kName; });
}

const char* Camera::ParamsInfo() const {
  return VisitCameraModel(
      model_id, [](auto model) { return decltype(model)::kParamsInfo; });
}

int Camera::NumParams() const { return CameraModelNumParams(model_id); }

int Camera::NumFocalParams() const {
  return VisitCameraModel(model_id,
                          [](auto model) { return decltype(model)::kNumFocal; });
}

bool Camera::HasDistortion() const {
  return VisitCameraModel(
      model_id, [](auto model) { return decltype(model)::kNumExtra > 0; });
}

double Camera::MeanFocalLength() const {
  const int num_focal = NumFocalParams();
  double sum = 0;
  for (int i = 0; i < num_focal; ++i) sum += params[i];
  return sum / num_focal;
}

void Camera::SetFocalLength(double focal) {
  const int num_focal = NumFocalParams();
  for (int i = 0; i < num_focal; ++i) params[i] = focal;
}

double Camera::CamFromImgThreshold(double pixels) const {
  return pixels / MeanFocalLength();
}

Eigen::Vector3d Camera::InCamAtRow(const Eigen::Vector3d& in_cam, double row,
                                   const Eigen::Vector3d& angular_velocity,
                                   const Eigen::Vector3d& linear_velocity) const {
  const double tau = RowTimeFraction(row, height) * readout_time;
  return in_cam + tau * (angular_velocity.cross(in_cam) + linear_velocity);
}

Eigen::Vector2d Camera::ImgFromCam(const Eigen::Vector3d& point_in_cam) const {
  Eigen::Vector2d pixel;
  VisitCameraModel(model_id, [&](auto model) {
    decltype(model)::ImgFromCam(params.data(), point_in_cam.x(),
                                point_in_cam.y(), point_in_cam.z(), &pixel.x(),
                                &pixel.y());
  });
  return pixel;
}

Eigen::Vector2d Camera::CamFromImg(const Eigen::Vector2d& pixel) const {
  Eigen::Vector2d normalized;
  VisitCameraModel(model_id, [&](auto model) {
    decltype(model)::CamFromImg(params.data(), pixel.x(), pixel.y(),
                                &normalized.x(), &normalized.y());
  });
  return normalized;
}

bool Camera::IsValid() const {
  if (static_cast<int>(params.size()) != NumParams()) return false;
  for (const double p : params) {
    if (!std::isfinite(p)) return false;
  }
  for (int i = 0; i < NumFocalParams(); ++i) {
    if (params[i] <= 0) return false;
  }
  return true;
}

}  // namespace flysfm
