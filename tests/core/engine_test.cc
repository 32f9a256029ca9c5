#include "core/engine.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <functional>
#include <random>

#include <catch2/catch.hpp>
#include <opencv2/imgcodecs.hpp>

#include "core/ablation.h"
#include "io/evaluation/evaluation.h"
#include "io/synthetic/synthetic_source.h"
#include "tests/testing/exif_jpeg.h"
#include "tests/testing/rendered_capture.h"
#include "tests/testing/sanitizer.h"

namespace flysfm {
namespace {

// Centre RMSE of the registered images after Sim3 alignment to the truth.
double CenterRmse(const Reconstruction& reconstruction, const SyntheticCapture& capture) {
  const std::optional<PositionErrors> errors =
      CompareCentersByName(reconstruction, capture.CameraCentres());
  REQUIRE(errors);
  return errors->rmse;
}

const SyntheticCapture& Capture() {
  static const SyntheticCapture capture = [] {
    SyntheticCaptureOptions options;
    // Smaller under a sanitizer (tests/testing/sanitizer.h).
    options.num_views = testing::kSanitizerBuild ? 8 : 12;
    options.seed = 3;
    return testing::RenderedCapture(options);
  }();
  return capture;
}

// Rendered pixels are exact up to interpolation: centres within 0.5 % of
// the walk.
const double kCenterTolerance = 0.005 * SyntheticCaptureOptions().path_length;

// What a run reported, call by call.
struct Run {
  std::vector<std::vector<ImageResult>> calls;
  std::vector<ImageResult> finish;

  std::vector<ImageResult> All() const {
    std::vector<ImageResult> all;
    for (const auto& call : calls) all.insert(all.end(), call.begin(), call.end());
    all.insert(all.end(), finish.begin(), finish.end());
    return all;
  }
};

Run Feed(Engine* engine, const std::vector<Frame>& frames) {
  Run run;
  for (const Frame& frame : frames) {
    run.calls.push_back(engine->AddImage(frame));
    REQUIRE_FALSE(run.calls.back().empty());
    CHECK(run.calls.back().front().name == frame.name);
  }
  run.finish = engine->Finish();
  return run;
}

// Every image registered, and reported registered exactly once.
void CheckAllRegisteredOnce(const Engine& engine, const Run& run, std::size_t num_frames) {
  CHECK(engine.reconstruction().NumRegisteredImages() == num_frames);
  CHECK(engine.PendingImageNames().empty());
  std::map<std::string, int> reported;
  for (const ImageResult& result : run.All()) {
    reported[result.name] += result.status == ImageStatus::kRegistered;
  }
  CHECK(reported.size() == num_frames);
  for (const auto& [name, count] : reported) {
    INFO(name);
    CHECK(count == 1);
  }
}

TEST_CASE("The engine registers a rendered capture with accurate poses") {
  Engine engine(Engine::Options(), Capture().camera);
  const Run run = Feed(&engine, Capture().frames);
  CheckAllRegisteredOnce(engine, run, Capture().frames.size());
  CHECK(engine.reconstruction().MeanReprojectionError() < 0.5);
  CHECK(CenterRmse(engine.reconstruction(), Capture()) < kCenterTolerance);
  // Known intrinsics: nothing to converge, no global BA before Finish().
  for (const ImageResult& result : run.All()) CHECK_FALSE(result.global_ba);
}

TEST_CASE("Prepare keeps what the frame says of itself: name, times, source tag") {
  Frame frame = Capture().frames.front();
  frame.timestamp = 12.5;
  frame.arrival = std::chrono::steady_clock::now();
  frame.source = "alice";
  const PreparedFrame prepared = Engine::Prepare(frame, Engine::Options());
  CHECK(prepared.frame.name == frame.name);
  CHECK(prepared.frame.timestamp == 12.5);
  CHECK(prepared.frame.arrival == frame.arrival);
  CHECK(prepared.frame.source == "alice");
  CHECK(prepared.frame.bytes.empty());
}

TEST_CASE("Image results: stage times add up, registrations carry their work, counts grow") {
  Engine engine(Engine::Options(), Capture().camera);
  int model_images = 0;
  for (const Frame& frame : Capture().frames) {
    PreparedFrame prepared = Engine::Prepare(frame, engine.options());
    const double prepare_ms = prepared.decode_ms + prepared.features_ms;
    const auto start = std::chrono::steady_clock::now();
    const std::vector<ImageResult> results = engine.AddImage(std::move(prepared));
    const double call_ms =
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start)
            .count();
    double sum_ms = 0;
    for (const ImageResult& result : results) {
      INFO(result.name);
      double stages = 0;
      for (const auto& [name, member] : StageTimes::Stages()) {
        CHECK(result.times.*member >= 0);
        stages += result.times.*member;
      }
      CHECK(result.times.total == Approx(stages));
      sum_ms += result.times.total;
      // Every result of a call describes the model as the call left it.
      CHECK(result.model_images == int(engine.reconstruction().NumRegisteredImages()));
      CHECK(result.model_points == int(engine.reconstruction().NumPoints3D()));
      if (result.status == ImageStatus::kRegistered) {
        // The work that registered it, wherever it happened (the first
        // call, a retry, the initial pair).
        CHECK(result.cam_from_world.has_value());
        CHECK(result.num_observations > 0);
      }
    }
    // Each stage is timed once: the call's results account for its work,
    // all but the bookkeeping between stages (generously bounded, since a
    // loaded machine may preempt anywhere).
    CHECK(sum_ms - prepare_ms <= call_ms + 0.5);
    CHECK(sum_ms - prepare_ms >= 0.8 * call_ms - 5);
    const ImageResult& own = results.front();
    if (own.status == ImageStatus::kRegistered && engine.initialized() && model_images > 0) {
      CHECK(own.times.registration > 0);
      CHECK(own.times.ba > 0);
      CHECK(own.ba_free_images > 0);
    }
    CHECK(own.model_images >= model_images);
    model_images = own.model_images;
  }
  CHECK(model_images == int(Capture().frames.size()));
}

TEST_CASE("A shuffled capture waits in the pending pool and registers in full, deterministically") {
  std::vector<Frame> frames = Capture().frames;
  std::mt19937 rng(11);
  std::shuffle(frames.begin(), frames.end(), rng);
  // The model as the last image left it, before Finish: the per-image path
  // is single-threaded and deterministic. Finish's adjustments run on two
  // threads, whose sums differ in the last bits from run to run.
  const auto run_once = [&](Run* run, Reconstruction* before_finish) {
    auto engine = std::make_unique<Engine>(Engine::Options(), Capture().camera);
    for (const Frame& frame : frames) run->calls.push_back(engine->AddImage(frame));
    *before_finish = engine->reconstruction();
    run->finish = engine->Finish();
    return engine;
  };
  Run run;
  Reconstruction model;
  const std::unique_ptr<Engine> engine = run_once(&run, &model);
  CheckAllRegisteredOnce(*engine, run, frames.size());
  CHECK(CenterRmse(engine->reconstruction(), Capture()) < kCenterTolerance);
  // Some image waited: it registered in a later call than its own.
  int registered_later = 0;
  for (const auto& call : run.calls) {
    registered_later += int(call.size()) - 1;
  }
  CHECK(registered_later + int(run.finish.size()) > 0);
  CHECK(std::any_of(run.calls.begin(), run.calls.end(), [](const auto& call) {
    return call.front().status == ImageStatus::kPending && !call.front().reason.empty();
  }));

  Run again;
  Reconstruction twin_model;
  const std::unique_ptr<Engine> twin = run_once(&again, &twin_model);
  for (const image_t id : model.RegisteredImageIds()) {
    const Rigid3d& a = *model.image(id).cam_from_world;
    const Rigid3d& b = *twin_model.image(id).cam_from_world;
    CHECK(a.rotation.coeffs() == b.rotation.coeffs());
    CHECK(a.translation == b.translation);
    // After Finish: the same to far below the poses' precision.
    const Rigid3d& c = *engine->reconstruction().image(id).cam_from_world;
    const Rigid3d& d = *twin->reconstruction().image(id).cam_from_world;
    CHECK((c.rotation.coeffs() - d.rotation.coeffs()).norm() < 1e-9);
    CHECK((c.translation - d.translation).norm() < 1e-9 * kCenterTolerance / 0.005);
  }
}

TEST_CASE("Every ablation switch still registers the capture accurately") {
  for (const EngineAblation& ablation : EngineAblations()) {
    INFO(ablation.name);
    Engine::Options options;
    ablation.apply(&options);
    Engine engine(options, Capture().camera);
    const Run run = Feed(&engine, Capture().frames);
    CheckAllRegisteredOnce(engine, run, Capture().frames.size());
    CHECK(CenterRmse(engine.reconstruction(), Capture()) < kCenterTolerance);
  }
}

TEST_CASE("Registered images keep only LSM windows, and the run needs none of the rest") {
  Engine engine(Engine::Options(), Capture().camera);
  const Run run = Feed(&engine, Capture().frames);
  CheckAllRegisteredOnce(engine, run, Capture().frames.size());
  // Every image registered: none is kept whole, each keeps tiles, and what
  // it keeps is less than its 8-bit pyramid (1 500 keypoints' windows leave
  // some of a 640 x 480 frame uncovered).
  const LsmImageStore& store = engine.lsm_images();
  CHECK(store.WholeImages().empty());
  CHECK(store.whole_bytes() == 0);
  const std::size_t pyramid_bytes = 640 * 480 * 21 / 16;
  CHECK(store.window_bytes() > 0);
  CHECK(store.window_bytes() < Capture().frames.size() * pyramid_bytes);
  CHECK(CenterRmse(engine.reconstruction(), Capture()) < kCenterTolerance);

  // With no budget for windows, older images drop out of LSM at once: the
  // capture still registers, from SIFT positions, to the same tolerance.
  Engine::Options options;
  options.lsm_images.window_budget_megabytes = 0;
  Engine forgetful(options, Capture().camera);
  const Run forgetful_run = Feed(&forgetful, Capture().frames);
  CheckAllRegisteredOnce(forgetful, forgetful_run, Capture().frames.size());
  CHECK(forgetful.lsm_images().window_bytes() == 0);
  CHECK(CenterRmse(forgetful.reconstruction(), Capture()) < kCenterTolerance);
}

TEST_CASE("Without intrinsics the engine self-calibrates the focal length") {
  Engine engine{Engine::Options()};
  const Run run = Feed(&engine, Capture().frames);
  CheckAllRegisteredOnce(engine, run, Capture().frames.size());
  const Reconstruction& model = engine.reconstruction();
  REQUIRE(model.cameras().size() == 1);
  const Camera& camera = model.cameras().begin()->second;
  // The guess starts 1.2 x 640 = 768 px against the true 500.
  CHECK(camera.MeanFocalLength() == Approx(Capture().camera.MeanFocalLength()).epsilon(0.02));
  CHECK(CenterRmse(model, Capture()) < 2 * kCenterTolerance);
}

TEST_CASE("A wrong EXIF focal length, half or double the true one, is recovered") {
  // The true 500 px on 640 x 480 is a 27 mm equivalent; the EXIF says 54 mm
  // (998 px) or 14 mm (259 px), as a body that reports the wrong lens does.
  for (const int equivalent_mm : {54, 14}) {
    INFO(equivalent_mm << " mm");
    std::vector<Frame> frames = Capture().frames;
    for (Frame& frame : frames) {
      frame.bytes = testing::JpegWithExif(cv::imdecode(frame.bytes, cv::IMREAD_COLOR),
                                          {{{EXIF_TAG_FOCAL_LENGTH_IN_35MM_FILM, equivalent_mm}}, {}});
    }
    Engine engine{Engine::Options()};
    const Run run = Feed(&engine, frames);
    CheckAllRegisteredOnce(engine, run, frames.size());
    const Reconstruction& model = engine.reconstruction();
    REQUIRE(model.cameras().size() == 1);
    CHECK(model.cameras().begin()->second.MeanFocalLength() ==
          Approx(Capture().camera.MeanFocalLength()).epsilon(0.02));
    CHECK(CenterRmse(model, Capture()) < 2 * kCenterTolerance);
  }
}

TEST_CASE("Guessed intrinsics get a global BA each time the model grows by a quarter") {
  Engine engine{Engine::Options()};
  const Run run = Feed(&engine, Capture().frames);
  std::vector<int> model_sizes;
  for (const ImageResult& result : run.All()) {
    if (result.global_ba) model_sizes.push_back(result.model_images);
  }
  REQUIRE_FALSE(model_sizes.empty());
  CHECK(model_sizes.front() <= 3);
  // Geometric, so their total cost is a constant factor of the last one's;
  // one more for the two-view start.
  const double num_images = double(Capture().frames.size());
  CHECK(double(model_sizes.size()) <=
        2 + std::ceil(std::log(num_images / 2) /
                      std::log(Engine::Options().self_calibration_growth)));
  SECTION("past self_calibration_max_observations, with fewer iterations") {
    // A budget of one observation: every BA gets the fewest iterations.
    Engine::Options options;
    options.self_calibration_max_observations = 1;
    options.self_calibration_min_iterations = 2;
    Engine cut(options);
    const Run cut_run = Feed(&cut, Capture().frames);
    int num_global_bas = 0;
    for (const ImageResult& result : cut_run.All()) {
      if (!result.global_ba) continue;
      ++num_global_bas;
      CHECK(result.global_ba_iterations <= 2);
    }
    CHECK(num_global_bas >= 1);
    CheckAllRegisteredOnce(cut, cut_run, Capture().frames.size());
    // Each goes on from where the last stopped, and Finish's BA is whole.
    const Reconstruction& model = cut.reconstruction();
    CHECK(model.cameras().begin()->second.MeanFocalLength() ==
          Approx(Capture().camera.MeanFocalLength()).epsilon(0.02));
    CHECK(CenterRmse(model, Capture()) < 2 * kCenterTolerance);
  }
  SECTION("switched off") {
    Engine::Options options;
    options.self_calibration_growth = 0;
    Engine off(options);
    for (const ImageResult& result : Feed(&off, Capture().frames).All()) {
      CHECK_FALSE(result.global_ba);
    }
  }
}

TEST_CASE("Two camera bodies, as their EXIF tells them, get a camera each") {
  // The same capture as if shot alternately by two bodies of one model:
  // each self-calibrates on its own images.
  std::vector<Frame> frames = Capture().frames;
  for (std::size_t i = 0; i < frames.size(); ++i) {
    const cv::Mat image = cv::imdecode(frames[i].bytes, cv::IMREAD_COLOR);
    frames[i].bytes = testing::JpegWithExif(
        image, {{}, {{EXIF_TAG_MAKE, "Nikon"},
                     {EXIF_TAG_MODEL, "D850"},
                     {EXIF_TAG_BODY_SERIAL_NUMBER, i % 2 ? "2001" : "2002"}}});
  }
  Engine engine{Engine::Options()};
  const Run run = Feed(&engine, frames);
  CheckAllRegisteredOnce(engine, run, frames.size());
  const Reconstruction& model = engine.reconstruction();
  REQUIRE(model.cameras().size() == 2);
  for (const auto& [camera_id, camera] : model.cameras()) {
    CHECK(camera.MeanFocalLength() ==
          Approx(Capture().camera.MeanFocalLength()).epsilon(0.02));
  }
  // Images arrive in frame order, so ids follow the frames: neighbours
  // alternate between the bodies.
  std::vector<camera_t> camera_of_frame;
  for (const auto& [image_id, image] : model.images()) camera_of_frame.push_back(image.camera_id);
  REQUIRE(camera_of_frame.size() == frames.size());
  for (std::size_t i = 0; i + 1 < frames.size(); ++i) {
    CHECK(camera_of_frame[i] != camera_of_frame[i + 1]);
  }
}

TEST_CASE("A failed initial pair leaves the shared intrinsics as they were") {
  Engine::Options options;
  // Nothing survives the filter after the initial pair's BA, so every pair
  // fails after its BA refined the (unknown) intrinsics.
  options.filter_max_error_px = 1e-9;
  Engine engine{options};
  std::optional<Camera> first;
  for (const Frame& frame : Capture().frames) {
    const std::vector<ImageResult> results = engine.AddImage(frame);
    REQUIRE(results.size() == 1);
    CHECK(results.front().status == ImageStatus::kPending);
    CHECK(results.front().reason == "no initial pair yet");
    const Camera& camera = engine.reconstruction().cameras().begin()->second;
    if (!first) first = camera;
    CHECK(camera.params == first->params);
  }
  CHECK_FALSE(engine.initialized());
  CHECK(first->MeanFocalLength() == Approx(1.2 * 640));
  CHECK(engine.reconstruction().NumRegisteredImages() == 0);
  CHECK(engine.reconstruction().NumPoints3D() == 0);
}

TEST_CASE("Unreadable images are counted rejections, and the run goes on") {
  Engine engine(Engine::Options(), Capture().camera);
  std::vector<Frame> frames = Capture().frames;
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
  CHECK(engine.reconstruction().NumRegisteredImages() == Capture().frames.size());
}

TEST_CASE("Finish tells its steps and each iteration of its adjustments, within its budget") {
  Engine engine(Engine::Options(), Capture().camera);
  for (const Frame& frame : Capture().frames) engine.AddImage(frame);
  std::vector<Engine::FinishProgress> told;
  engine.Finish([&](const Engine::FinishProgress& progress) { told.push_back(progress); });
  REQUIRE(!told.empty());
  CHECK(told.front().step == Engine::FinishProgress::Step::kRetry);
  int adjust = 0, snoop = 0;
  for (std::size_t i = 0; i < told.size(); ++i) {
    const Engine::FinishProgress& progress = told[i];
    if (i > 0) CHECK(progress.elapsed_s >= told[i - 1].elapsed_s);
    if (progress.step == Engine::FinishProgress::Step::kRetry) continue;
    adjust += progress.step == Engine::FinishProgress::Step::kAdjust;
    snoop += progress.step == Engine::FinishProgress::Step::kSnoop;
    CHECK(progress.iteration <= progress.max_iterations);
    REQUIRE(progress.remaining_s);
    // Never beyond the budget: a model this small gets min_seconds.
    CHECK(*progress.remaining_s <= Engine::Options().finishing.min_seconds);
    if (progress.step == Engine::FinishProgress::Step::kSnoop) {
      CHECK(progress.round >= 1);
      CHECK(progress.round <= progress.max_rounds);
    }
  }
  // The global BA's start and iterations, then the snooping's adjustments.
  CHECK(adjust >= 2);
  CHECK(snoop >= 1);
}

TEST_CASE("With no time left for it, the end starts no adjustment iteration") {
  SyntheticCaptureOptions capture_options;
  capture_options.num_views = 6;
  capture_options.seed = 4;
  const SyntheticCapture capture = testing::RenderedCapture(capture_options);
  Engine::Options options;
  options.finishing.max_share_of_run = 0;
  options.finishing.min_seconds = 0;
  Engine engine(options, capture.camera);
  for (const Frame& frame : capture.frames) engine.AddImage(frame);
  std::vector<Engine::FinishProgress> told;
  engine.Finish([&](const Engine::FinishProgress& progress) { told.push_back(progress); });
  int num_adjust = 0;
  for (const Engine::FinishProgress& progress : told) {
    // The global BA evaluates its start (iteration 0) and stops there; the
    // snooping, which needs time left, never begins.
    CHECK(progress.step != Engine::FinishProgress::Step::kSnoop);
    if (progress.step != Engine::FinishProgress::Step::kAdjust) continue;
    ++num_adjust;
    CHECK(progress.iteration == 0);
    CHECK(progress.remaining_s == 0.0);
  }
  CHECK(num_adjust == 1);
  CHECK(engine.reconstruction().NumRegisteredImages() == capture.frames.size());
}

TEST_CASE("Invalid options are refused, naming the option") {
  Engine::Options options;
  options.max_verified_pairs = 0;
  std::string problem;
  CHECK_FALSE(options.Check(&problem));
  CHECK(problem.find("max_verified_pairs") != std::string::npos);
  CHECK_THROWS_WITH(Engine(options), Catch::Contains("max_verified_pairs"));
  options = Engine::Options();
  options.lsm_images.num_pyramid_levels = 1;
  CHECK_THROWS_WITH(Engine(options), Catch::Contains("num_pyramid_levels"));
  options = Engine::Options();
  options.self_calibration_growth = 1;
  CHECK_THROWS_WITH(Engine(options), Catch::Contains("self_calibration_growth"));
  options = Engine::Options();
  options.self_calibration_min_iterations = 0;
  CHECK_THROWS_WITH(Engine(options), Catch::Contains("self_calibration_min_iterations"));
}

}  // namespace
}  // namespace flysfm
