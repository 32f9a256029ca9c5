#include "io/formats/trajectory.h"

#include <fstream>
#include <map>

#include <catch2/catch.hpp>

#include "tests/testing/synthetic.h"
#include "tests/testing/temp_dir.h"

namespace flysfm {
namespace {

TEST_CASE("TUM trajectories round-trip") {
  std::mt19937 rng(4);
  std::vector<StampedPose> poses;
  for (int i = 0; i < 20; ++i) {
    poses.push_back({1305031102.175304 + i / 30.0,
                     Rigid3d(testing::RandomRotation(rng), testing::RandomUnitVector(rng))});
  }
  const auto path = testing::MakeTempDir("trajectory_test") / "trajectory.txt";
  WriteTumTrajectory(poses, path);
  const std::vector<StampedPose> read = ReadTumTrajectory(path);
  REQUIRE(read.size() == poses.size());
  for (std::size_t i = 0; i < poses.size(); ++i) {
    CHECK(read[i].timestamp == Approx(poses[i].timestamp).margin(1e-6));
    CHECK((read[i].world_from_cam.translation - poses[i].world_from_cam.translation).norm() < 1e-12);
    CHECK(RotationDifferenceDeg(read[i].world_from_cam, poses[i].world_from_cam) < 1e-9);
  }
}

TEST_CASE("Malformed trajectory lines name their line") {
  const auto path = testing::MakeTempDir("trajectory_test") / "bad_trajectory.txt";
  std::ofstream(path) << "# comment\n1 0 0 0 0 0 0 1\n2 0 0 zero 0 0 0 1\n";
  CHECK_THROWS_WITH(ReadTumTrajectory(path), Catch::Matchers::Contains(":3:"));
}

TEST_CASE("Image names give timestamps") {
  CHECK(TimestampFromImageName("rgb/1305031102.175304.png", -1) == 1305031102.175304);
  CHECK(TimestampFromImageName("0007.jpg", -1) == 7);
  CHECK(TimestampFromImageName("IMG_0007.JPG", 3) == 3);
  CHECK(TimestampFromImageName("templeR0013.png", 12) == 12);
}

TEST_CASE("A trajectory is stamped by name, else by capture time, not by registration order") {
  Reconstruction model;
  const camera_t camera_id = model.AddCamera(Camera::FromFocal(CameraModelId::kPinhole, 500, 640, 480));
  // As an initial pair registers them: the second photo first.
  const image_t first = model.AddImage("photo_a.jpg", camera_id, {});
  const image_t second = model.AddImage("photo_b.jpg", camera_id, {});
  const image_t numbered = model.AddImage("0042.jpg", camera_id, {});
  model.image(first).capture_time = 0;
  model.image(second).capture_time = 1;
  model.image(numbered).capture_time = 2;
  Rigid3d pose;
  pose.translation = Eigen::Vector3d(1, 0, 0);
  model.RegisterImage(second, pose);
  model.RegisterImage(first, Rigid3d());
  model.RegisterImage(numbered, Rigid3d());
  const std::vector<StampedPose> poses = TrajectoryOf(model);
  REQUIRE(poses.size() == 3);
  std::map<double, double> x_by_timestamp;
  for (const StampedPose& stamped : poses) {
    x_by_timestamp[stamped.timestamp] = stamped.world_from_cam.translation.x();
  }
  CHECK(x_by_timestamp == std::map<double, double>{{0, 0}, {1, -1}, {42, 0}});
}

TEST_CASE("Association pairs nearest timestamps within the tolerance, once each") {
  std::vector<StampedPose> reference, estimated;
  for (int i = 0; i < 100; ++i) reference.push_back({i * 0.01, Rigid3d()});
  for (double t : {0.0, 0.304, 0.3051, 0.5, 5.0}) estimated.push_back({t, Rigid3d()});
  const auto pairs = AssociateByTimestamp(estimated, reference, 0.02);
  // 0.304 and 0.3051 both want reference 0.30/0.31: 0.3051 is nearest 0.31,
  // 0.304 nearest 0.30; 5.0 has none within 0.02 s.
  REQUIRE(pairs.size() == 4);
  CHECK(pairs[0] == std::make_pair<std::size_t, std::size_t>(0, 0));
  CHECK(pairs[1] == std::make_pair<std::size_t, std::size_t>(1, 30));
  CHECK(pairs[2] == std::make_pair<std::size_t, std::size_t>(2, 31));
  CHECK(pairs[3] == std::make_pair<std::size_t, std::size_t>(3, 50));
}

}  // namespace
}  // namespace flysfm
