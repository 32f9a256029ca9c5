#include "quality/coverage.h"

#include <cmath>
#include <random>

#include <catch2/catch.hpp>

#include "geometry/camera.h"

namespace flysfm {
namespace {

constexpr double kPi = 3.14159265358979323846;

// A box-shaped building, x and z in [-2, 2], from the ground (y = 0) to its
// roof (y = -3; y is down, as in a camera held upright), its four walls and
// roof sampled every 0.25 units, with a millimetre of jitter so that no four
// points are exactly coplanar.
struct Wall {
  Eigen::Vector3d normal;
  std::vector<Eigen::Vector3d> points;
};

std::vector<Wall> Building() {
  std::mt19937 random(7);
  std::uniform_real_distribution<double> jitter(-1e-3, 1e-3);
  const auto noisy = [&](const Eigen::Vector3d& p) -> Eigen::Vector3d {
    return p + Eigen::Vector3d(jitter(random), jitter(random), jitter(random));
  };
  std::vector<Wall> walls;
  for (const double sign : {1.0, -1.0}) {
    for (const int axis : {0, 2}) {
      Wall wall;
      wall.normal = Eigen::Vector3d::Zero();
      wall.normal[axis] = sign;
      for (int a = 0; a <= 16; ++a) {
        for (int b = 0; b <= 12; ++b) {
          Eigen::Vector3d p;
          p[axis] = 2 * sign;
          p[2 - axis] = -2 + 0.25 * a;
          p[1] = -0.25 * b;
          wall.points.push_back(noisy(p));
        }
      }
      walls.push_back(wall);
    }
  }
  Wall roof;
  roof.normal = Eigen::Vector3d(0, -1, 0);
  for (int a = 1; a < 16; ++a) {
    for (int b = 1; b < 16; ++b) {
      roof.points.push_back(noisy(Eigen::Vector3d(-2 + 0.25 * a, -3, -2 + 0.25 * b)));
    }
  }
  walls.push_back(roof);
  return walls;
}

// A camera at azimuth `degrees` on a circle of radius 9 around the building,
// `height` above the ground (8: above its roof), looking at its middle.
Rigid3d CameraAt(double degrees, double height = 8) {
  const double a = degrees * kPi / 180.0;
  const Eigen::Vector3d center(9 * std::cos(a), -height, 9 * std::sin(a));
  const Eigen::Vector3d z = (Eigen::Vector3d(0, -1.5, 0) - center).normalized();
  const Eigen::Vector3d y = (Eigen::Vector3d(0, 1, 0) - z.y() * z).normalized();
  const Eigen::Vector3d x = y.cross(z);
  Eigen::Matrix3d rotation;
  rotation << x.transpose(), y.transpose(), z.transpose();
  return Rigid3d(rotation, -rotation * center);
}

// The model the engine would hold: every wall point a camera faces (at less
// than 80 degrees from its normal: SIFT matches nothing more oblique) and
// sees in its image, with its track; points seen once are not in it.
Reconstruction Model(const std::vector<double>& azimuths, double height = 8) {
  Reconstruction model;
  const Camera camera = Camera::FromFocal(CameraModelId::kPinhole, 500, 640, 480);
  const camera_t camera_id = model.AddCamera(camera);
  const std::vector<Wall> walls = Building();
  std::vector<Eigen::Vector3d> points;
  std::vector<Eigen::Vector3d> normals;
  for (const Wall& wall : walls) {
    for (const Eigen::Vector3d& p : wall.points) {
      points.push_back(p);
      normals.push_back(wall.normal);
    }
  }
  std::vector<std::vector<TrackElement>> tracks(points.size());
  std::vector<Rigid3d> poses;
  for (std::size_t i = 0; i < azimuths.size(); ++i) {
    const Rigid3d pose = CameraAt(azimuths[i], height);
    const Eigen::Vector3d center = ProjectionCenter(pose);
    std::vector<Eigen::Vector2d> keypoints;
    for (std::size_t p = 0; p < points.size(); ++p) {
      const Eigen::Vector3d to_camera = center - points[p];
      if (normals[p].dot(to_camera) < std::cos(80 * kPi / 180) * to_camera.norm()) continue;
      const Eigen::Vector3d in_cam = pose.rotation * points[p] + pose.translation;
      if (in_cam.z() <= 0) continue;
      const Eigen::Vector2d pixel = camera.ImgFromCam(in_cam);
      if (pixel.x() < 0 || pixel.y() < 0 || pixel.x() >= 640 || pixel.y() >= 480) continue;
      tracks[p].push_back({image_t(i + 1), point2D_t(keypoints.size())});
      keypoints.push_back(pixel);
    }
    model.AddImage("shot" + std::to_string(i), camera_id, keypoints, image_t(i + 1));
    model.RegisterImage(image_t(i + 1), pose);
  }
  for (std::size_t p = 0; p < points.size(); ++p) {
    if (tracks[p].size() >= 2) model.AddPoint3D(points[p], tracks[p]);
  }
  return model;
}

std::vector<double> Ring(bool skip_east) {
  std::vector<double> azimuths;
  for (int degrees = 0; degrees < 360; degrees += 15) {
    const double x = 9 * std::cos(degrees * kPi / 180.0);
    // Skipping the east wall (x = 2): no shot from where it could be seen.
    if (skip_east && x > 2) continue;
    azimuths.push_back(degrees);
  }
  return azimuths;
}

bool OnEastWall(const Coverage::Face& face) {
  const Eigen::Vector3d centroid = (face.corners[0] + face.corners[1] + face.corners[2]) / 3;
  return face.normal.x() > 0.9 && centroid.x() > 1.9;
}

// Area-weighted precision and recall of `predicted` against `truth`, over the
// faces a photographer can reach (undersides left out).
template <typename Predicted, typename Truth>
std::pair<double, double> PrecisionRecall(const Coverage& coverage, Predicted predicted,
                                          Truth truth) {
  double both = 0, predicted_area = 0, true_area = 0;
  for (const Coverage::Face& face : coverage.faces()) {
    if (face.face_class == Coverage::FaceClass::kUnderside) continue;
    const bool p = predicted(face);
    const bool t = truth(face);
    if (p) predicted_area += face.area;
    if (t) true_area += face.area;
    if (p && t) both += face.area;
  }
  return {predicted_area > 0 ? both / predicted_area : 0, true_area > 0 ? both / true_area : 0};
}

TEST_CASE("Coverage: a building shot all around is well covered, its floor is an underside") {
  Coverage coverage;
  coverage.Update(Model(Ring(false)));
  const Coverage::Summary& summary = coverage.summary();
  INFO("faces " << summary.faces << " area " << summary.area << " well "
                << summary.well_covered_area << " few " << summary.few_views_area << " narrow "
                << summary.narrow_angle_area << " underside " << summary.underside_area);
  // Up is minus y: the cameras were held upright.
  CHECK(coverage.up().y() == Approx(-1).margin(1e-9));
  // Four walls of 4 x 3 and a roof of 4 x 4 (3.5 x 3.5 of roof points, and
  // the hull's slopes from the roof's edge to the walls' tops).
  CHECK(summary.area == Approx(64).epsilon(0.05));
  CHECK(summary.well_covered_share >= 0.95);
  // The floor, 4 x 4, faces the ground.
  CHECK(summary.underside_area == Approx(16).epsilon(0.05));
  CHECK(coverage.suggestions().empty());
}

TEST_CASE("Coverage: a roof above every shot is out of reach, apart from the shares") {
  // From 1.5 units up, below the roof (3): its points are never seen, and
  // the hull closes over the walls' tops.
  Coverage coverage;
  coverage.Update(Model(Ring(false), 1.5));
  const Coverage::Summary& summary = coverage.summary();
  INFO("area " << summary.area << " out of reach " << summary.out_of_reach_area << " share "
               << summary.well_covered_share);
  CHECK(summary.out_of_reach_area == Approx(16).epsilon(0.1));
  CHECK(summary.area == Approx(48).epsilon(0.05));
  CHECK(summary.well_covered_share >= 0.95);
  for (const Coverage::Suggestion& suggestion : coverage.suggestions()) {
    CHECK(suggestion.reason.find("the top") == std::string::npos);
  }
}

TEST_CASE("Coverage: a skipped wall is marked, and the first suggestion looks at it") {
  Coverage coverage;
  coverage.Update(Model(Ring(true)));
  const Coverage::Summary& summary = coverage.summary();
  const auto under = [](const Coverage::Face& face) {
    return face.face_class == Coverage::FaceClass::kFewViews ||
           face.face_class == Coverage::FaceClass::kNarrowAngle;
  };
  const auto [precision, recall] = PrecisionRecall(coverage, under, OnEastWall);
  INFO("precision " << precision << " recall " << recall << " share "
                    << summary.well_covered_share);
  CHECK(precision >= 0.9);
  CHECK(recall >= 0.9);
  // One wall of 12 in 64 missing.
  CHECK(summary.well_covered_share == Approx(52.0 / 64.0).margin(0.05));

  REQUIRE_FALSE(coverage.suggestions().empty());
  const Coverage::Suggestion& first = coverage.suggestions().front();
  INFO("position " << first.position.transpose() << " direction "
                   << first.direction.transpose() << " reason " << first.reason);
  // The nearest shots (due north and south of the building) are some 100
  // degrees round from the wall's normal: the suggestion is a step of 30
  // degrees from them, east of the wall's plane (it sees the wall), looking
  // west at it, at the photographer's height.
  CHECK(first.step);
  CHECK(first.position.x() > 2);
  CHECK(first.direction.x() < 0);
  CHECK(first.position.y() == Approx(-8).margin(1e-6));
  CHECK(first.area_share == Approx(12.0 / 64.0).margin(0.05));
  CHECK(first.reason.find("fewer than 3 photos") != std::string::npos);
  CHECK(first.reason.find("a step towards it") != std::string::npos);
  // Its pose looks where it says, image up along up.
  const Eigen::Vector3d axis = first.cam_from_world.rotation.inverse() * Eigen::Vector3d::UnitZ();
  CHECK((axis - first.direction).norm() < 1e-9);
  CHECK((ProjectionCenter(first.cam_from_world) - first.position).norm() < 1e-9);
}

TEST_CASE("Coverage: a wall shot from one position only is seen under too narrow an angle") {
  std::vector<double> azimuths = Ring(true);
  // Three shots of the east wall from nearly one place: 1 degree apart on
  // the circle, 0.16 units, under 2 degrees from the wall.
  for (const double degrees : {-1.0, 0.0, 1.0}) azimuths.push_back(degrees);
  Coverage coverage;
  coverage.Update(Model(azimuths));
  const auto narrow = [](const Coverage::Face& face) {
    return face.face_class == Coverage::FaceClass::kNarrowAngle;
  };
  const auto [precision, recall] = PrecisionRecall(coverage, narrow, OnEastWall);
  INFO("precision " << precision << " recall " << recall);
  CHECK(precision >= 0.9);
  CHECK(recall >= 0.9);
  REQUIRE_FALSE(coverage.suggestions().empty());
  CHECK(coverage.suggestions().front().reason.find("less than 10 degrees") != std::string::npos);
  // The three shots face the wall: no step needed.
  CHECK_FALSE(coverage.suggestions().front().step);
}

// A building with a courtyard cut into its east side, x in [1, 2] and z in
// [-1, 1], the union of three boxes (x0, x1, z0, z1; y from -3 to 0): a
// concave object, whose hull would close the courtyard's opening.
struct Box {
  double x0, x1, z0, z1;
  bool Inside(const Eigen::Vector3d& p, double margin) const {
    return p.x() > x0 + margin && p.x() < x1 - margin && p.z() > z0 + margin &&
           p.z() < z1 - margin && p.y() > -3 + margin && p.y() < -margin;
  }
};
const std::vector<Box> kCourtyardBuilding = {
    {-2, 1, -2, 2}, {1, 2, -2, -1}, {1, 2, 1, 2}};

bool InsideBuilding(const Eigen::Vector3d& p, double margin) {
  for (const Box& box : kCourtyardBuilding) {
    if (box.Inside(p, margin)) return true;
  }
  return false;
}

// Whether the segment from a surface point (just off it along its normal) to
// a camera stays out of the building: sampled every 2 cm.
bool Unoccluded(const Eigen::Vector3d& point, const Eigen::Vector3d& normal,
                const Eigen::Vector3d& camera) {
  const Eigen::Vector3d from = point + 0.01 * normal;
  const int steps = int((camera - from).norm() / 0.02) + 1;
  for (int k = 0; k <= steps; ++k) {
    if (InsideBuilding(from + (camera - from) * (double(k) / steps), 0.001)) return false;
  }
  return true;
}

Reconstruction CourtyardModel() {
  std::mt19937 random(11);
  std::uniform_real_distribution<double> jitter(-1e-3, 1e-3);
  std::vector<Eigen::Vector3d> points;
  std::vector<Eigen::Vector3d> normals;
  // Every box face sampled every 0.25; what lies inside the building (the
  // faces the boxes share) or outside it (off the union) is not surface.
  const auto add = [&](const Eigen::Vector3d& p, const Eigen::Vector3d& normal) {
    if (InsideBuilding(p + 0.05 * normal, 0) || !InsideBuilding(p - 0.05 * normal, 0)) return;
    points.push_back(p + Eigen::Vector3d(jitter(random), jitter(random), jitter(random)));
    normals.push_back(normal);
  };
  for (const Box& box : kCourtyardBuilding) {
    for (double x = box.x0; x <= box.x1 + 1e-9; x += 0.25) {
      for (double y = 0; y >= -3 - 1e-9; y -= 0.25) {
        add({x, y, box.z0}, {0, 0, -1});
        add({x, y, box.z1}, {0, 0, 1});
      }
      for (double z = box.z0; z <= box.z1 + 1e-9; z += 0.25) {
        if (x > box.x0 + 1e-9 && x < box.x1 - 1e-9 && z > box.z0 + 1e-9 && z < box.z1 - 1e-9) {
          add({x, -3, z}, {0, -1, 0});
        }
      }
    }
    for (double z = box.z0; z <= box.z1 + 1e-9; z += 0.25) {
      for (double y = 0; y >= -3 - 1e-9; y -= 0.25) {
        add({box.x0, y, z}, {-1, 0, 0});
        add({box.x1, y, z}, {1, 0, 0});
      }
    }
  }
  // The ground around it, out to 4 units, the courtyard's included: without
  // it no ray would reach the courtyard's lowest corner, and the space there
  // could not be told from the building.
  for (double x = -4; x <= 4 + 1e-9; x += 0.25) {
    for (double z = -4; z <= 4 + 1e-9; z += 0.25) {
      const Eigen::Vector3d p(x, 0, z);
      if (InsideBuilding(p + Eigen::Vector3d(0, -0.05, 0), 0)) continue;
      points.push_back(p + Eigen::Vector3d(jitter(random), jitter(random), jitter(random)));
      normals.push_back({0, -1, 0});
    }
  }
  Reconstruction model;
  const Camera camera = Camera::FromFocal(CameraModelId::kPinhole, 500, 640, 480);
  const camera_t camera_id = model.AddCamera(camera);
  std::vector<std::vector<TrackElement>> tracks(points.size());
  image_t image_id = 1;
  for (int degrees = 0; degrees < 360; degrees += 10) {
    const Rigid3d pose = CameraAt(degrees);
    const Eigen::Vector3d center = ProjectionCenter(pose);
    std::vector<Eigen::Vector2d> keypoints;
    for (std::size_t p = 0; p < points.size(); ++p) {
      const Eigen::Vector3d to_camera = center - points[p];
      if (normals[p].dot(to_camera) < std::cos(80 * kPi / 180) * to_camera.norm()) continue;
      if (!Unoccluded(points[p], normals[p], center)) continue;
      const Eigen::Vector3d in_cam = pose.rotation * points[p] + pose.translation;
      const Eigen::Vector2d pixel = camera.ImgFromCam(in_cam);
      if (in_cam.z() <= 0 || pixel.x() < 0 || pixel.y() < 0 || pixel.x() >= 640 ||
          pixel.y() >= 480) {
        continue;
      }
      tracks[p].push_back({image_id, point2D_t(keypoints.size())});
      keypoints.push_back(pixel);
    }
    model.AddImage("shot" + std::to_string(image_id), camera_id, keypoints, image_id);
    model.RegisterImage(image_id, pose);
    ++image_id;
  }
  for (std::size_t p = 0; p < points.size(); ++p) {
    if (tracks[p].size() >= 2) model.AddPoint3D(points[p], tracks[p]);
  }
  return model;
}

TEST_CASE("Coverage: the rays carve a courtyard out of the points' hull") {
  Coverage coverage;
  coverage.Update(CourtyardModel());
  double opening = 0;    // across the courtyard's mouth, where the hull closes it
  double back_wall = 0;  // the courtyard's back wall, x = 1, facing east
  for (const Coverage::Face& face : coverage.faces()) {
    const Eigen::Vector3d c = (face.corners[0] + face.corners[1] + face.corners[2]) / 3;
    if (c.x() > 1.9 && c.x() < 2.1 && std::abs(c.z()) < 0.9 && std::abs(face.normal.x()) > 0.5) {
      opening += face.area;
    }
    // Within one point spacing of the wall, facing within 30 degrees of east:
    // a surface made of points 0.25 apart is no finer than that.
    if (std::abs(c.x() - 1) < 0.25 && std::abs(c.z()) < 0.9 && face.normal.x() > 0.87) {
      back_wall += face.area;
    }
  }
  const Coverage::Summary& summary = coverage.summary();
  INFO("opening " << opening << " back wall " << back_wall << " share "
                  << summary.well_covered_share << " rays " << summary.rays);
  // The mouth is 2 x 3. Of the back wall, 1.8 x 3 away from the side walls'
  // corners, the top 0.25 bevels into the roof (whose points stop 0.25 short
  // of its edges): 1.8 x 2.75 is wall.
  CHECK(opening < 0.05 * 6);
  CHECK(back_wall > 0.9 * 1.8 * 2.75);
}

TEST_CASE("Coverage: too little of a model has no surface, and bad options are refused") {
  Reconstruction empty;
  Coverage coverage;
  coverage.Update(empty);
  CHECK(coverage.faces().empty());
  CHECK(coverage.summary().well_covered_share == 0);
  Coverage::Options options;
  options.max_incidence_deg = 0;
  CHECK_THROWS_WITH(Coverage(options), Catch::Contains("max_incidence_deg"));
  options = Coverage::Options();
  options.min_views = 1;
  CHECK_THROWS_WITH(Coverage(options), Catch::Contains("min_views"));
}

}  // namespace
}  // namespace flysfm
