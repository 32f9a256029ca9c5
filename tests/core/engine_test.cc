#include "core/engine.h"

#include <catch2/catch.hpp>

#include "io/evaluation/evaluation.h"
#include "io/synthetic/synthetic_source.h"

namespace flysfm {
namespace {

// Centre RMSE of the registered images after Sim3 alignment to the truth.
double CenterRmse(const Reconstruction& reconstruction, const SyntheticCapture& capture) {
  std::map<std::string, Eigen::Vector3d> truth;
  for (std::size_t i = 0; i < capture.frames.size(); ++i) {
    truth[capture.frames[i].name] = ProjectionCenter(capture.cams_from_world[i]);
  }
  const std::optional<PositionErrors> errors = CompareCentersByName(reconstruction, truth);
  REQUIRE(errors);
  return errors->rmse;
}

SyntheticCapture RenderCapture(int num_views, std::uint32_t seed) {
  SyntheticCaptureOptions options;
  options.num_views = num_views;
  options.seed = seed;
  return MakeSyntheticCapture(options);
}

TEST_CASE("The engine registers a rendered capture with accurate poses") {
  const SyntheticCapture capture = RenderCapture(12, 3);
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
  CHECK(CenterRmse(model, capture) < 0.005 * SyntheticCaptureOptions().path_length);
}

TEST_CASE("Unreadable images are counted rejections, and the run goes on") {
  const SyntheticCapture capture = RenderCapture(8, 5);
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
