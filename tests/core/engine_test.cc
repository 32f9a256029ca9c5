#include "core/engine.h"

#include <random>

#include <catch2/catch.hpp>
#include <opencv2/imgcodecs.hpp>

#include "geometry/similarity.h"
#include "tests/testing/render.h"

namespace flysfm {
namespace {

// A hand-held walk past the facet scene: cameras about 5 m from the wall,
// spread over 3 m, each looking at the scene's centre with a little jitter.
struct Capture {
  Camera camera = Camera::FromString("PINHOLE 500,500,320,240", 640, 480);
  std::vector<Rigid3d> cams_from_world;
  std::vector<Frame> frames;
};

Capture RenderCapture(int num_views, std::uint32_t seed) {
  const testing::TexturedScene scene = testing::MakeFacetScene(seed);
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> jitter(-1.0, 1.0);
  Capture capture;
  for (int i = 0; i < num_views; ++i) {
    const double s = double(i) / (num_views - 1) - 0.5;
    const Eigen::Vector3d center(3.0 * s, 0.2 * jitter(rng), -5.0 + 0.2 * jitter(rng));
    const Eigen::Vector3d target(0.3 * jitter(rng), 0.2 * jitter(rng), 1.0);
    const Eigen::Vector3d forward = (target - center).normalized();
    const Eigen::Vector3d right = Eigen::Vector3d::UnitY().cross(forward).normalized();
    Eigen::Matrix3d world_from_cam;
    world_from_cam << right, forward.cross(right), forward;
    const Rigid3d cam_from_world(Eigen::Matrix3d(world_from_cam.transpose()),
                                 -(world_from_cam.transpose() * center));
    capture.cams_from_world.push_back(cam_from_world);
    const testing::RenderedView view =
        testing::Render(scene, capture.camera, cam_from_world, /*supersampling=*/2);
    Frame frame;
    frame.name = "view" + std::to_string(100 + i) + ".png";
    cv::imencode(".png", view.image, frame.bytes);
    capture.frames.push_back(std::move(frame));
  }
  return capture;
}

// Camera centres after the Sim3 that best aligns them to the truth.
double CenterRmseAfterSim3(const Reconstruction& reconstruction, const Capture& capture) {
  std::vector<Eigen::Vector3d> estimated, truth;
  for (const auto& [id, image] : reconstruction.images()) {
    if (!image.IsRegistered()) continue;
    const int index = std::stoi(image.name.substr(4, 3)) - 100;
    estimated.push_back(ProjectionCenter(*image.cam_from_world));
    truth.push_back(ProjectionCenter(capture.cams_from_world[index]));
  }
  const std::optional<Sim3d> truth_from_estimate = SimilarityFromPoints(estimated, truth);
  REQUIRE(truth_from_estimate);
  double sum = 0;
  for (std::size_t i = 0; i < estimated.size(); ++i) {
    sum += (*truth_from_estimate * estimated[i] - truth[i]).squaredNorm();
  }
  return std::sqrt(sum / estimated.size());
}

TEST_CASE("The engine registers a rendered capture with accurate poses") {
  const Capture capture = RenderCapture(12, 3);
  Engine engine(Engine::Options(), capture.camera);
  int reported_registered = 0;
  for (const Frame& frame : capture.frames) {
    const std::vector<ImageResult> results = engine.AddImage(frame);
    REQUIRE_FALSE(results.empty());
    CHECK(results.front().name == frame.name);
    CHECK(results.front().status != ImageStatus::kRejected);
    for (const ImageResult& result : results) {
      reported_registered += result.status == ImageStatus::kRegistered;
    }
  }
  for (const ImageResult& result : engine.Finish()) {
    reported_registered += result.status == ImageStatus::kRegistered;
  }
  const Reconstruction& model = engine.reconstruction();
  // Every image registered, each reported once as registered.
  CHECK(model.NumRegisteredImages() == capture.frames.size());
  CHECK(reported_registered == int(capture.frames.size()));
  CHECK(engine.PendingImageNames().empty());
  // Rendered pixels are exact up to interpolation: sub-pixel reprojection.
  CHECK(model.MeanReprojectionError() < 0.5);
  // Centres within 0.5 % of the 3 m path (the demo criterion).
  CHECK(CenterRmseAfterSim3(model, capture) < 0.005 * 3.0);
}

TEST_CASE("Unreadable images are counted rejections, and the run goes on") {
  const Capture capture = RenderCapture(8, 5);
  Engine engine(Engine::Options(), capture.camera);
  std::vector<Frame> frames = capture.frames;
  Frame truncated = frames[2];
  truncated.name = "truncated.png";
  truncated.bytes.resize(truncated.bytes.size() / 2);
  Frame empty;
  empty.name = "empty.jpg";
  Frame missing;
  missing.name = "missing.jpg";
  missing.path = "/nonexistent/flysfm/missing.jpg";
  frames.insert(frames.begin() + 3, {truncated, empty, missing});
  for (const Frame& frame : frames) {
    const ImageResult result = engine.AddImage(frame).front();
    const bool bad = frame.name == "truncated.png" || frame.name == "empty.jpg" ||
                     frame.name == "missing.jpg";
    CHECK((result.status == ImageStatus::kRejected) == bad);
    if (bad) CHECK_FALSE(result.reason.empty());
  }
  engine.Finish();
  CHECK(engine.num_rejected() == 3);
  CHECK(engine.reconstruction().NumRegisteredImages() == capture.frames.size());
}

}  // namespace
}  // namespace flysfm
