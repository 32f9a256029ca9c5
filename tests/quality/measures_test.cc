#include "quality/measures.h"

#include <cmath>

#include <catch2/catch.hpp>
#include <Eigen/Geometry>

namespace flysfm {
namespace {

// A camera at `center` looking along +z.
Rigid3d LookingAlongZ(const Eigen::Vector3d& center) {
  return Rigid3d(Eigen::Quaterniond::Identity(), -center);
}

TEST_CASE("A fronto-parallel stereo pair's point covariance is the textbook one") {
  const double f = 800, baseline = 0.5, depth = 10, sigma = 0.7;
  const Camera camera = Camera::FromString("PINHOLE 800,800,500,400", 1000, 800);
  const std::vector<PointView> views = {
      {LookingAlongZ(Eigen::Vector3d::Zero()), &camera},
      {LookingAlongZ(Eigen::Vector3d(baseline, 0, 0)), &camera}};
  // Half-way between the cameras, so that x and z are uncorrelated.
  const Eigen::Vector3d xyz(baseline / 2, 0, depth);
  const std::optional<Eigen::Matrix3d> covariance = PointCovariance(xyz, views, sigma);
  REQUIRE(covariance);
  // Depth from disparity f B / Z, whose noise is sigma sqrt(2); across the
  // rays, the mean of two measurements.
  const double depth_sd = depth * depth * sigma * std::sqrt(2.0) / (f * baseline);
  const double lateral_sd = depth * sigma / (f * std::sqrt(2.0));
  CHECK(std::sqrt((*covariance)(2, 2)) == Approx(depth_sd).epsilon(1e-6));
  CHECK(std::sqrt((*covariance)(0, 0)) == Approx(lateral_sd).epsilon(1e-6));
  CHECK(std::sqrt((*covariance)(1, 1)) == Approx(lateral_sd).epsilon(1e-6));
  CHECK((*covariance)(0, 2) == Approx(0).margin(1e-9 * depth_sd * depth_sd));
  CHECK(LargestStdDev(*covariance) == Approx(depth_sd).epsilon(1e-6));
  // The covariance scales with sigma^2.
  CHECK(LargestStdDev(*PointCovariance(xyz, views, 2 * sigma)) ==
        Approx(2 * LargestStdDev(*covariance)).epsilon(1e-12));
}

TEST_CASE("A point seen once, or along parallel rays, has no defined uncertainty") {
  const Camera camera = Camera::FromString("PINHOLE 800,800,500,400", 1000, 800);
  const Eigen::Vector3d xyz(0.2, 0.1, 5);
  const PointView view{LookingAlongZ(Eigen::Vector3d::Zero()), &camera};
  CHECK_FALSE(PointCovariance(xyz, {view}, 1.0));
  CHECK_FALSE(PointCovariance(xyz, {view, view}, 1.0));
  // Two cameras on the same ray through the point, one nearer: 0 degrees.
  const PointView nearer{LookingAlongZ(0.5 * xyz), &camera};
  CHECK_FALSE(PointCovariance(xyz, {view, nearer}, 1.0));
  // Behind a camera.
  const PointView behind{LookingAlongZ(Eigen::Vector3d(0, 0, 10)), &camera};
  CHECK_FALSE(PointCovariance(xyz, {view, behind}, 1.0));
}

TEST_CASE("The projection Jacobian is f / z and -f x / z^2 for a pinhole") {
  const Camera camera = Camera::FromString("PINHOLE 800,600,500,400", 1000, 800);
  const Eigen::Vector3d in_cam(0.4, -0.2, 2);
  const auto jacobian = ProjectionJacobian(camera, in_cam);
  REQUIRE(jacobian);
  CHECK((*jacobian)(0, 0) == Approx(800 / 2.0).epsilon(1e-8));
  CHECK((*jacobian)(0, 1) == Approx(0).margin(1e-6));
  CHECK((*jacobian)(0, 2) == Approx(-800 * 0.4 / 4).epsilon(1e-8));
  CHECK((*jacobian)(1, 1) == Approx(600 / 2.0).epsilon(1e-8));
  CHECK((*jacobian)(1, 2) == Approx(600 * 0.2 / 4).epsilon(1e-8));
  CHECK_FALSE(ProjectionJacobian(camera, Eigen::Vector3d(0, 0, -1)));
}

TEST_CASE("The triangulation angle is the widest pair's") {
  const Eigen::Vector3d xyz(0, 0, 10);
  // From (+-10 tan 20deg, 0, 0): 40 degrees between the outer two.
  const double x = 10 * std::tan(20 * M_PI / 180);
  CHECK(MaxTriangulationAngleDeg(xyz, {{-x, 0, 0}, {0, 0, 0}, {x, 0, 0}}) ==
        Approx(40).epsilon(1e-12));
  CHECK(MaxTriangulationAngleDeg(xyz, {{0, 0, 0}}) == 0);
  CHECK(MaxTriangulationAngleDeg(xyz, {{0, 0, 0}, {0, 0, 5}}) == 0);
}

TEST_CASE("The convex hull area ignores inner points and is 0 on a line") {
  CHECK(ConvexHullArea({{0, 0}, {4, 0}, {4, 3}, {0, 3}, {1, 1}, {2, 2}, {4, 1}}) == 12);
  CHECK(ConvexHullArea({{0, 0}, {6, 0}, {2, 4}}) == 12);
  CHECK(ConvexHullArea({{0, 0}, {1, 1}, {2, 2}, {3, 3}}) == 0);
  CHECK(ConvexHullArea({{0, 0}, {1, 1}}) == 0);
}

// A camera at height `height` above the plane z = 0, looking down (+z in the
// camera is -z in the world), over an n x n grid of half-width `half_width`.
struct PlaneShot {
  Camera camera = Camera::FromString("PINHOLE 1000,1000,960,640", 1920, 1280);
  Rigid3d cam_from_world;
  std::vector<Eigen::Vector3d> points;

  PlaneShot(double height, int n, double half_width) {
    // World x -> camera x, world y -> camera -y, world z -> camera -z.
    const Eigen::Matrix3d rotation = Eigen::Vector3d(1, -1, -1).asDiagonal();
    cam_from_world = Rigid3d(Eigen::Quaterniond(rotation), -rotation * Eigen::Vector3d(0, 0, height));
    for (int i = 0; i < n; ++i) {
      for (int j = 0; j < n; ++j) {
        points.emplace_back(half_width * (2.0 * i / (n - 1) - 1),
                            half_width * (2.0 * j / (n - 1) - 1), 0);
      }
    }
  }
  std::optional<double> CenterSigma(double sigma = 1.0) const {
    const auto covariance = PoseCovariance(cam_from_world, camera, points, sigma);
    if (!covariance) return std::nullopt;
    return LargestStdDev(covariance->bottomRightCorner<3, 3>());
  }
};

TEST_CASE("A camera's centre uncertainty falls as 1/sqrt(n) with n times the points") {
  PlaneShot shot(10, 5, 4);
  const std::optional<double> once = shot.CenterSigma();
  REQUIRE(once);
  const std::vector<Eigen::Vector3d> grid = shot.points;
  for (int copies = 2; copies <= 9; copies *= 3) {
    shot.points.clear();
    for (int k = 0; k < copies; ++k) shot.points.insert(shot.points.end(), grid.begin(), grid.end());
    INFO(copies);
    CHECK(*shot.CenterSigma() == Approx(*once / std::sqrt(double(copies))).epsilon(1e-9));
  }
  // Linear in sigma.
  CHECK(*PlaneShot(10, 5, 4).CenterSigma(0.5) == Approx(*once / 2).epsilon(1e-9));
}

TEST_CASE("A wider spread of points pins the camera's centre down better") {
  // The same 25 points over a quarter, half and all of the view.
  const double narrow = *PlaneShot(10, 5, 1).CenterSigma();
  const double medium = *PlaneShot(10, 5, 2).CenterSigma();
  const double wide = *PlaneShot(10, 5, 4).CenterSigma();
  CHECK(medium < narrow);
  CHECK(wide < medium);
}

TEST_CASE("The centre covariance is the inverse of the numeric pose Jacobians' information") {
  const PlaneShot shot(10, 4, 3);
  const Eigen::Matrix3d rotation = shot.cam_from_world.rotation.toRotationMatrix();
  const Eigen::Vector3d center = ProjectionCenter(shot.cam_from_world);
  // pixel(omega, C) with in_cam = exp([omega]x) R (X - C), differentiated
  // numerically here, analytically in PoseCovariance.
  const auto project = [&](const Eigen::Matrix<double, 6, 1>& p, const Eigen::Vector3d& x) {
    const double angle = p.head<3>().norm();
    const Eigen::Matrix3d delta =
        angle > 0 ? Eigen::AngleAxisd(angle, p.head<3>() / angle).toRotationMatrix()
                  : Eigen::Matrix3d::Identity();
    return shot.camera.ImgFromCam(delta * rotation * (x - (center + p.tail<3>())));
  };
  Eigen::Matrix<double, 6, 6> information = Eigen::Matrix<double, 6, 6>::Zero();
  for (const Eigen::Vector3d& x : shot.points) {
    Eigen::Matrix<double, 2, 6> jacobian;
    for (int k = 0; k < 6; ++k) {
      Eigen::Matrix<double, 6, 1> step = Eigen::Matrix<double, 6, 1>::Zero();
      step(k) = 1e-6;
      jacobian.col(k) = (project(step, x) - project(-step, x)) / 2e-6;
    }
    information += jacobian.transpose() * jacobian;
  }
  const Eigen::Matrix3d expected = information.inverse().bottomRightCorner<3, 3>();
  const auto covariance = PoseCovariance(shot.cam_from_world, shot.camera, shot.points, 1.0);
  REQUIRE(covariance);
  CHECK((covariance->bottomRightCorner<3, 3>() - expected).norm() < 1e-5 * expected.norm());
}

TEST_CASE("Fewer than 3 points, or all on one ray, leave a camera's centre undefined") {
  PlaneShot shot(10, 5, 4);
  shot.points.resize(2);
  CHECK_FALSE(shot.CenterSigma());
  // Five points along the ray through the image centre.
  shot.points.clear();
  for (int k = 0; k < 5; ++k) shot.points.emplace_back(0, 0, -2.0 * k);
  CHECK_FALSE(shot.CenterSigma());
}

TEST_CASE("MeasurePoint and MeasureImage read the model") {
  const double f = 800, baseline = 0.5, depth = 10;
  Reconstruction r;
  const camera_t camera_id = r.AddCamera(Camera::FromString("PINHOLE 800,800,500,400", 1000, 800));
  const Eigen::Vector3d xyz(baseline / 2, 0, depth);
  const std::vector<Eigen::Vector3d> centers = {Eigen::Vector3d::Zero(), {baseline, 0, 0}};
  std::vector<image_t> images;
  for (int i = 0; i < 2; ++i) {
    const Rigid3d pose = LookingAlongZ(centers[i]);
    const Eigen::Vector2d pixel = r.camera(camera_id).ImgFromCam(pose * xyz);
    // The observed keypoint 0.3 px right of the projection in the second
    // image; four more keypoints at the corners of the image.
    std::vector<Eigen::Vector2d> keypoints = {pixel + Eigen::Vector2d(0.3 * i, 0), {0, 0},
                                              {999, 0}, {0, 799}, {999, 799}};
    images.push_back(r.AddImage("i" + std::to_string(i), camera_id, keypoints));
    r.RegisterImage(images.back(), pose);
  }
  const point3D_t id = r.AddPoint3D(xyz, {{images[0], 0}, {images[1], 0}});
  const PointQuality point = MeasurePoint(r, id, 1.0);
  CHECK(point.views == 2);
  CHECK(point.max_angle_deg == Approx(2 * std::atan(baseline / 2 / depth) * 180 / M_PI));
  CHECK(point.error_px == Approx(0.15));
  CHECK(point.squared_error_sum == Approx(0.09));
  REQUIRE(point.sigma);
  CHECK(*point.sigma == Approx(depth * depth * std::sqrt(2.0) / (f * baseline)).epsilon(1e-6));

  ImageQuality image = MeasureImage(r, images[0], 1.0);
  CHECK(image.inliers == 1);
  CHECK(image.spread == 0);
  CHECK_FALSE(image.center_sigma);
  // Four more points seen at the pixel centres of the image's corners.
  for (point2D_t k = 1; k <= 4; ++k) {
    const Eigen::Vector3d ray(r.camera(camera_id).CamFromImg(r.image(images[0]).points2D[k].xy).homogeneous());
    r.AddPoint3D(depth * ray, {{images[0], k}});
  }
  image = MeasureImage(r, images[0], 1.0);
  CHECK(image.inliers == 5);
  CHECK(image.spread == Approx(999.0 * 799 / (1000 * 800)));
  CHECK(image.center_sigma);
}

}  // namespace
}  // namespace flysfm
