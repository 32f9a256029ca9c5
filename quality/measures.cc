#include "quality/measures.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>

namespace flysfm {
namespace {

// Below this share of the largest eigenvalue the information matrix is
// taken as singular: far above rounding (1e-16), far below any geometry a
// model keeps (parallel rays within 1e-4 degrees).
constexpr double kMinEigenvalueRatio = 1e-12;

Eigen::Matrix3d Skew(const Eigen::Vector3d& v) {
  Eigen::Matrix3d m;
  m << 0, -v.z(), v.y(), v.z(), 0, -v.x(), -v.y(), v.x(), 0;
  return m;
}

// The inverse of a symmetric information matrix, or nullopt when it is
// singular. Scaled to a unit diagonal first, so that parameters in different
// units (radians, model units) do not make a well-posed problem look
// singular.
template <int N>
std::optional<Eigen::Matrix<double, N, N>> InvertInformation(
    const Eigen::Matrix<double, N, N>& information) {
  using Matrix = Eigen::Matrix<double, N, N>;
  const Eigen::Matrix<double, N, 1> diagonal = information.diagonal();
  if (!(diagonal.minCoeff() > 0) || !information.allFinite()) return std::nullopt;
  const Eigen::Matrix<double, N, 1> scale = diagonal.cwiseSqrt().cwiseInverse();
  const Matrix scaled = scale.asDiagonal() * information * scale.asDiagonal();
  const Eigen::SelfAdjointEigenSolver<Matrix> solver(scaled);
  if (solver.info() != Eigen::Success) return std::nullopt;
  const auto& eigenvalues = solver.eigenvalues();  // ascending
  if (!(eigenvalues(0) > kMinEigenvalueRatio * eigenvalues(N - 1))) return std::nullopt;
  const Matrix scaled_inverse = solver.eigenvectors() *
                                eigenvalues.cwiseInverse().asDiagonal() *
                                solver.eigenvectors().transpose();
  return Matrix(scale.asDiagonal() * scaled_inverse * scale.asDiagonal());
}

}  // namespace

std::optional<Eigen::Matrix<double, 2, 3>> ProjectionJacobian(const Camera& camera,
                                                              const Eigen::Vector3d& in_cam) {
  if (!(in_cam.z() > std::numeric_limits<double>::epsilon() * in_cam.norm())) {
    return std::nullopt;
  }
  // A step of 1e-6 of the distance: truncation (h^2) and rounding
  // (1e-16 / h) errors both near 1e-10 of the derivative.
  const double h = 1e-6 * in_cam.norm();
  Eigen::Matrix<double, 2, 3> jacobian;
  for (int k = 0; k < 3; ++k) {
    Eigen::Vector3d plus = in_cam, minus = in_cam;
    plus(k) += h;
    minus(k) -= h;
    jacobian.col(k) = (camera.ImgFromCam(plus) - camera.ImgFromCam(minus)) / (2 * h);
  }
  return jacobian;
}

std::optional<Eigen::Matrix3d> ViewInformation(const Eigen::Vector3d& xyz, const PointView& view) {
  const std::optional<Eigen::Matrix<double, 2, 3>> projection =
      ProjectionJacobian(*view.camera, view.cam_from_world * xyz);
  if (!projection) return std::nullopt;
  // d in_cam / d xyz is the rotation.
  const Eigen::Matrix<double, 2, 3> jacobian =
      *projection * view.cam_from_world.rotation.toRotationMatrix();
  return Eigen::Matrix3d(jacobian.transpose() * jacobian);
}

std::optional<Eigen::Matrix3d> CovarianceFromInformation(const Eigen::Matrix3d& information,
                                                         double sigma_px) {
  const std::optional<Eigen::Matrix3d> inverse = InvertInformation<3>(information);
  if (!inverse) return std::nullopt;
  return Eigen::Matrix3d(sigma_px * sigma_px * *inverse);
}

std::optional<Eigen::Matrix3d> PointCovariance(const Eigen::Vector3d& xyz,
                                               const std::vector<PointView>& views,
                                               double sigma_px) {
  if (views.size() < 2) return std::nullopt;
  Eigen::Matrix3d information = Eigen::Matrix3d::Zero();
  for (const PointView& view : views) {
    const std::optional<Eigen::Matrix3d> share = ViewInformation(xyz, view);
    if (!share) return std::nullopt;
    information += *share;
  }
  return CovarianceFromInformation(information, sigma_px);
}

std::optional<Eigen::Matrix<double, 6, 6>> PoseCovariance(
    const Rigid3d& cam_from_world, const Camera& camera,
    const std::vector<Eigen::Vector3d>& points, double sigma_px) {
  if (points.size() < 3) return std::nullopt;
  const Eigen::Matrix3d rotation = cam_from_world.rotation.toRotationMatrix();
  Eigen::Matrix<double, 6, 6> information = Eigen::Matrix<double, 6, 6>::Zero();
  for (const Eigen::Vector3d& xyz : points) {
    const Eigen::Vector3d in_cam = cam_from_world * xyz;
    const std::optional<Eigen::Matrix<double, 2, 3>> projection =
        ProjectionJacobian(camera, in_cam);
    if (!projection) return std::nullopt;
    // in_cam = exp([omega]x) R (X - C) at omega = 0:
    // d/d omega = -[in_cam]x, d/d C = -R.
    Eigen::Matrix<double, 3, 6> d_in_cam;
    d_in_cam.leftCols<3>() = -Skew(in_cam);
    d_in_cam.rightCols<3>() = -rotation;
    const Eigen::Matrix<double, 2, 6> jacobian = *projection * d_in_cam;
    information += jacobian.transpose() * jacobian;
  }
  const std::optional<Eigen::Matrix<double, 6, 6>> inverse =
      InvertInformation<6>(information);
  if (!inverse) return std::nullopt;
  return Eigen::Matrix<double, 6, 6>(sigma_px * sigma_px * *inverse);
}

double LargestStdDev(const Eigen::Matrix3d& covariance) {
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> solver(covariance,
                                                              Eigen::EigenvaluesOnly);
  return std::sqrt(std::max(0.0, solver.eigenvalues()(2)));
}

double RayAngle(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return std::atan2(a.cross(b).norm(), a.dot(b));
}

double MaxTriangulationAngleDeg(const Eigen::Vector3d& xyz,
                                const std::vector<Eigen::Vector3d>& centers) {
  std::vector<Eigen::Vector3d> rays;
  rays.reserve(centers.size());
  for (const Eigen::Vector3d& center : centers) rays.push_back((xyz - center).normalized());
  double max_angle = 0;
  for (std::size_t i = 0; i < rays.size(); ++i) {
    for (std::size_t j = i + 1; j < rays.size(); ++j) {
      max_angle = std::max(max_angle, RayAngle(rays[i], rays[j]));
    }
  }
  return max_angle * 180.0 / M_PI;
}

double ConvexHullArea(std::vector<Eigen::Vector2d> points) {
  if (points.size() < 3) return 0;
  // Andrew's monotone chain.
  std::sort(points.begin(), points.end(), [](const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
    return a.x() < b.x() || (a.x() == b.x() && a.y() < b.y());
  });
  const auto cross = [](const Eigen::Vector2d& o, const Eigen::Vector2d& a,
                        const Eigen::Vector2d& b) {
    return (a.x() - o.x()) * (b.y() - o.y()) - (a.y() - o.y()) * (b.x() - o.x());
  };
  std::vector<Eigen::Vector2d> hull(2 * points.size());
  std::size_t k = 0;
  for (std::size_t i = 0; i < points.size(); ++i) {
    while (k >= 2 && cross(hull[k - 2], hull[k - 1], points[i]) <= 0) --k;
    hull[k++] = points[i];
  }
  for (std::size_t i = points.size() - 1, lower = k + 1; i > 0; --i) {
    while (k >= lower && cross(hull[k - 2], hull[k - 1], points[i - 1]) <= 0) --k;
    hull[k++] = points[i - 1];
  }
  // The last vertex repeats the first.
  double twice_area = 0;
  for (std::size_t i = 0; i + 1 < k; ++i) {
    twice_area += hull[i].x() * hull[i + 1].y() - hull[i + 1].x() * hull[i].y();
  }
  return 0.5 * std::abs(twice_area);
}

PointQuality MeasurePoint(const Reconstruction& reconstruction, point3D_t point3D_id,
                          double sigma_px, std::optional<Eigen::Matrix3d>* information) {
  const Point3D& point = reconstruction.point3D(point3D_id);
  PointQuality quality;
  quality.views = int(point.track.size());
  std::vector<Eigen::Vector3d> centers;
  double error_sum = 0;
  std::optional<Eigen::Matrix3d> sum = Eigen::Matrix3d::Zero();
  for (const TrackElement& element : point.track) {
    const Image& image = reconstruction.image(element.image_id);
    centers.push_back(ProjectionCenter(*image.cam_from_world));
    const double error =
        reconstruction.ReprojectionError(element.image_id, element.point2D_idx, point.xyz);
    error_sum += error;
    quality.squared_error_sum += error * error;
    if (!sum) continue;
    const std::optional<Eigen::Matrix3d> share = ViewInformation(
        point.xyz, {*image.cam_from_world, &reconstruction.camera(image.camera_id)});
    if (share) {
      *sum += *share;
    } else {
      sum.reset();
    }
  }
  if (!point.track.empty()) quality.error_px = error_sum / double(point.track.size());
  quality.max_angle_deg = MaxTriangulationAngleDeg(point.xyz, centers);
  if (sum && point.track.size() >= 2) {
    if (const std::optional<Eigen::Matrix3d> covariance =
            CovarianceFromInformation(*sum, sigma_px)) {
      quality.sigma = LargestStdDev(*covariance);
    }
  }
  if (information) *information = sum;
  return quality;
}

ImageQuality MeasureImage(const Reconstruction& reconstruction, image_t image_id,
                          double sigma_px) {
  const Image& image = reconstruction.image(image_id);
  const Camera& camera = reconstruction.camera(image.camera_id);
  ImageQuality quality;
  std::vector<Eigen::Vector2d> keypoints;
  std::vector<Eigen::Vector3d> points;
  for (std::size_t idx = 0; idx < image.points2D.size(); ++idx) {
    const Point2D& point2D = image.points2D[idx];
    if (!point2D.HasPoint3D()) continue;
    keypoints.push_back(point2D.xy);
    points.push_back(reconstruction.point3D(point2D.point3D_id).xyz);
    const double error = reconstruction.ReprojectionError(image_id, point2D_t(idx), points.back());
    quality.squared_error_sum += error * error;
  }
  quality.inliers = int(points.size());
  const double area = double(camera.width) * double(camera.height);
  if (area > 0) quality.spread = std::min(1.0, ConvexHullArea(std::move(keypoints)) / area);
  if (image.IsRegistered()) {
    if (const std::optional<Eigen::Matrix<double, 6, 6>> covariance =
            PoseCovariance(*image.cam_from_world, camera, points, sigma_px)) {
      quality.center_sigma = LargestStdDev(covariance->bottomRightCorner<3, 3>());
    }
  }
  return quality;
}

}  // namespace flysfm
