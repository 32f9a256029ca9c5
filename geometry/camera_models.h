#pragma once

// Camera models with COLMAP's names, ids and parameter orders, so that models
// round-trip with COLMAP's files. Every model lays its parameters out as
// [focal (1 or 2), cx, cy, distortion...]. Projection is templated for Ceres'
// automatic differentiation; unprojection inverts the distortion iteratively.

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

namespace flysfm {

enum class CameraModelId : int {
  kSimplePinhole = 0,
  kPinhole = 1,
  kSimpleRadial = 2,
  kRadial = 3,
  kOpenCV = 4,
  kFullOpenCV = 6,
};

// Projection and unprojection shared by all models; `Model` supplies the
// focal count, the number of distortion parameters and Distortion().
template <typename Model>
struct CameraModelBase {
  static constexpr int kNumParams = Model::kNumFocal + 2 + Model::kNumExtra;

  // (u, v, w) in camera coordinates -> pixel (x, y).
  template <typename T>
  static void ImgFromCam(const T* params, T u, T v, T w, T* x, T* y) {
    u /= w;
    v /= w;
    T du = T(0);
    T dv = T(0);
    if constexpr (Model::kNumExtra > 0) {
      Model::Distortion(params + Model::kNumFocal + 2, u, v, &du, &dv);
    }
    const T& fx = params[0];
    const T& fy = params[Model::kNumFocal - 1];
    *x = fx * (u + du) + params[Model::kNumFocal];
    *y = fy * (v + dv) + params[Model::kNumFocal + 1];
  }

  // Pixel (x, y) -> normalized ray (u, v, 1), undistorted by Newton's method.
  static void CamFromImg(const double* params, double x, double y, double* u,
                         double* v) {
    const double fx = params[0];
    const double fy = params[Model::kNumFocal - 1];
    *u = (x - params[Model::kNumFocal]) / fx;
    *v = (y - params[Model::kNumFocal + 1]) / fy;
    if constexpr (Model::kNumExtra > 0) {
      IterativeUndistortion(params + Model::kNumFocal + 2, u, v);
    }
  }

 private:
  // Solves p + d(p) = p_distorted for p. The Jacobian is taken by central
  // differences: Newton then still converges to machine precision, and the
  // models need no hand-written derivatives.
  static void IterativeUndistortion(const double* extra, double* u, double* v) {
    constexpr int kMaxIterations = 100;
    constexpr double kStep = 1e-7;
    constexpr double kTolerance = 1e-20;
    const double target_u = *u;
    const double target_v = *v;
    double pu = *u;
    double pv = *v;
    for (int i = 0; i < kMaxIterations; ++i) {
      double du, dv;
      Model::Distortion(extra, pu, pv, &du, &dv);
      const double ru = pu + du - target_u;
      const double rv = pv + dv - target_v;
      const double hu = kStep * std::max(1.0, std::abs(pu));
      const double hv = kStep * std::max(1.0, std::abs(pv));
      double du0, dv0, du1, dv1;
      Model::Distortion(extra, pu - hu, pv, &du0, &dv0);
      Model::Distortion(extra, pu + hu, pv, &du1, &dv1);
      const double j00 = 1.0 + (du1 - du0) / (2 * hu);
      const double j10 = (dv1 - dv0) / (2 * hu);
      Model::Distortion(extra, pu, pv - hv, &du0, &dv0);
      Model::Distortion(extra, pu, pv + hv, &du1, &dv1);
      const double j01 = (du1 - du0) / (2 * hv);
      const double j11 = 1.0 + (dv1 - dv0) / (2 * hv);
      const double det = j00 * j11 - j01 * j10;
      if (det == 0.0 || !std::isfinite(det)) break;
      const double step_u = (j11 * ru - j01 * rv) / det;
      const double step_v = (-j10 * ru + j00 * rv) / det;
      pu -= step_u;
      pv -= step_v;
      if (step_u * step_u + step_v * step_v <
          kTolerance * (1.0 + pu * pu + pv * pv)) {
        break;
      }
    }
    *u = pu;
    *v = pv;
  }
};

struct SimplePinholeModel : CameraModelBase<SimplePinholeModel> {
  static constexpr CameraModelId kId = CameraModelId::kSimplePinhole;
  static constexpr const char* kName = "SIMPLE_PINHOLE";
  static constexpr const char* kParamsInfo = "f, cx, cy";
  static constexpr int kNumFocal = 1;
  static constexpr int kNumExtra = 0;
};

struct PinholeModel : CameraModelBase<PinholeModel> {
  static constexpr CameraModelId kId = CameraModelId::kPinhole;
  static constexpr const char* kName = "PINHOLE";
  static constexpr const char* kParamsInfo = "fx, fy, cx, cy";
  static constexpr int kNumFocal = 2;
  static constexpr int kNumExtra = 0;
};

struct SimpleRadialModel : CameraModelBase<SimpleRadialModel> {
  static constexpr CameraModelId kId = CameraModelId::kSimpleRadial;
  static constexpr const char* kName = "SIMPLE_RADIAL";
  static constexpr const char* kParamsInfo = "f, cx, cy, k";
  static constexpr int kNumFocal = 1;
  static constexpr int kNumExtra = 1;

  template <typename T>
  static void Distortion(const T* extra, T u, T v, T* du, T* dv) {
    const T radial = extra[0] * (u * u + v * v);
    *du = u * radial;
    *dv = v * radial;
  }
};

struct RadialModel : CameraModelBase<RadialModel> {
  static constexpr CameraModelId kId = CameraModelId::kRadial;
  static constexpr const char* kName = "RADIAL";
  static constexpr const char* kParamsInfo = "f, cx, cy, k1, k2";
  static constexpr int kNumFocal = 1;
  static constexpr int kNumExtra = 2;

  template <typename T>
  static void Distortion(const T* extra, T u, T v, T* du, T* dv) {
    const T r2 = u * u + v * v;
    const T radial = extra[0] * r2 + extra[1] * r2 * r2;
    *du = u * radial;
    *dv = v * radial;
  }
};

struct OpenCVModel : CameraModelBase<OpenCVModel> {
  static constexpr CameraModelId kId = CameraModelId::kOpenCV;
  static constexpr const char* kName = "OPENCV";
  static constexpr const char* kParamsInfo = "fx, fy, cx, cy, k1, k2, p1, p2";
  static constexpr int kNumFocal = 2;
  static constexpr int kNumExtra = 4;

  template <typename T>
  static void Distortion(const T* extra, T u, T v, T* du, T* dv) {
    const T& k1 = extra[0];
    const T& k2 = extra[1];
    const T& p1 = extra[2];
    const T& p2 = extra[3];
    const T u2 = u * u;
    const T v2 = v * v;
    const T uv = u * v;
    const T r2 = u2 + v2;
    const T radial = k1 * r2 + k2 * r2 * r2;
    *du = u * radial + T(2) * p1 * uv + p2 * (r2 + T(2) * u2);
    *dv = v * radial + T(2) * p2 * uv + p1 * (r2 + T(2) * v2);
  }
};

struct FullOpenCVModel : CameraModelBase<FullOpenCVModel> {
  static constexpr CameraModelId kId = CameraModelId::kFullOpenCV;
  static constexpr const char* kName = "FULL_OPENCV";
  static constexpr const char* kParamsInfo =
      "fx, fy, cx, cy, k1, k2, p1, p2, k3, k4, k5, k6";
  static constexpr int kNumFocal = 2;
  static constexpr int kNumExtra = 8;

  template <typename T>
  static void Distortion(const T* extra, T u, T v, T* du, T* dv) {
    const T& k1 = extra[0];
    const T& k2 = extra[1];
    const T& p1 = extra[2];
    const T& p2 = extra[3];
    const T& k3 = extra[4];
    const T& k4 = extra[5];
    const T& k5 = extra[6];
    const T& k6 = extra[7];
    const T u2 = u * u;
    const T v2 = v * v;
    const T uv = u * v;
    const T r2 = u2 + v2;
    const T r4 = r2 * r2;
    const T r6 = r4 * r2;
    const T radial = (T(1) + k1 * r2 + k2 * r4 + k3 * r6) /
                     (T(1) + k4 * r2 + k5 * r4 + k6 * r6);
    *du = u * radial + T(2) * p1 * uv + p2 * (r2 + T(2) * u2) - u;
    *dv = v * radial + T(2) * p2 * uv + p1 * (r2 + T(2) * v2) - v;
  }
};

// Calls visitor(Model{}) with the model type of `id`, e.g.
//   VisitCameraModel(id, [&](auto model) { using M = decltype(model); ... });
// An id outside the enum is an internal error (ids from outside are checked
// when parsed).
template <typename Visitor>
decltype(auto) VisitCameraModel(CameraModelId id, Visitor&& visitor) {
  switch (id) {
    case CameraModelId::kSimplePinhole: return visitor(SimplePinholeModel{});
    case CameraModelId::kPinhole: return visitor(PinholeModel{});
    case CameraModelId::kSimpleRadial: return visitor(SimpleRadialModel{});
    case CameraModelId::kRadial: return visitor(RadialModel{});
    case CameraModelId::kOpenCV: return visitor(OpenCVModel{});
    case CameraModelId::kFullOpenCV: return visitor(FullOpenCVModel{});
  }
  throw std::logic_error("unknown camera model id " +
                         std::to_string(static_cast<int>(id)));
}

}  // namespace flysfm
