// Engine::WriteImageRecord / WriteSnapshot / Restore: an engine restored from
// a checkpoint continues the same model as one that never stopped.

#include <map>
#include <sstream>

#include <catch2/catch.hpp>

#include "core/engine.h"
#include "io/evaluation/evaluation.h"
#include "io/synthetic/synthetic_source.h"
#include "tests/testing/frame_files.h"
#include "tests/testing/temp_dir.h"
#include "tests/testing/rendered_capture.h"
#include "tests/testing/sanitizer.h"

namespace flysfm {
namespace {

struct Files {
  SyntheticCapture capture;
  // The frames as files: a restored engine decodes the images LSM still
  // searches again from theirs.
  std::vector<Frame> frames;
};

const Files& Capture() {
  static const Files files = [] {
    SyntheticCaptureOptions options;
    // Smaller under a sanitizer (tests/testing/sanitizer.h); the sections
    // need more than 6.
    options.num_views = testing::kSanitizerBuild ? 8 : 10;
    options.seed = 5;
    Files files{testing::RenderedCapture(options), {}};
    files.frames = testing::WriteFrameFiles(files.capture.frames,
                                            testing::MakeTempDir("engine_checkpoint"));
    return files;
  }();
  return files;
}

// A whole checkpoint in memory: the snapshot, each image's record and the
// windows of the images kept as windows.
struct Checkpoint {
  std::string snapshot;
  std::string retrieval_model;
  std::map<image_t, std::string> records;
  std::map<image_t, std::string> windows;
};

// `all_windows`: every image's windows are written, as for images that came
// as bytes; otherwise only those of images without a file, as the run's
// Checkpointer does (the others are cut again from their files).
Checkpoint Save(const Engine& engine, bool all_windows = true) {
  Checkpoint checkpoint;
  for (const auto& [image_id, image] : engine.reconstruction().images()) {
    std::ostringstream record;
    engine.WriteImageRecord(image_id, record);
    checkpoint.records[image_id] = record.str();
    const LsmImageStore& lsm = engine.lsm_images();
    if (lsm.HasPixels(image_id) && !lsm.IsWhole(image_id) &&
        (all_windows || !engine.HasImageFile(image_id))) {
      std::ostringstream windows;
      lsm.WriteWindows(image_id, windows);
      checkpoint.windows[image_id] = windows.str();
    }
  }
  std::ostringstream model;
  engine.WriteRetrievalModel(model);
  checkpoint.retrieval_model = model.str();
  std::ostringstream snapshot;
  engine.WriteSnapshot(snapshot);
  checkpoint.snapshot = snapshot.str();
  return checkpoint;
}

std::function<std::unique_ptr<std::istream>(image_t)> Opener(
    const std::map<image_t, std::string>& files) {
  return [&files](image_t image_id) -> std::unique_ptr<std::istream> {
    const auto it = files.find(image_id);
    if (it == files.end()) return nullptr;
    return std::make_unique<std::istringstream>(it->second);
  };
}

void Restore(const Checkpoint& checkpoint, Engine* engine) {
  std::istringstream snapshot(checkpoint.snapshot);
  Engine::CheckpointFiles files;
  files.record = Opener(checkpoint.records);
  files.windows = Opener(checkpoint.windows);
  files.retrieval_model = [&](int) {
    return std::make_unique<std::istringstream>(checkpoint.retrieval_model);
  };
  engine->Restore(snapshot, files);
}

void Feed(Engine* engine, std::size_t begin, std::size_t end) {
  for (std::size_t i = begin; i < end; ++i) engine->AddImage(Capture().frames[i]);
}

// Camera centres by image name.
std::map<std::string, Eigen::Vector3d> Centers(const Reconstruction& model) {
  std::map<std::string, Eigen::Vector3d> centers;
  for (const image_t image_id : model.RegisteredImageIds()) {
    const Image& image = model.image(image_id);
    centers[image.name] = ProjectionCenter(*image.cam_from_world);
  }
  return centers;
}

// The two models hold the same images, points and poses. Both engines did
// the same arithmetic, but the restored model's point table iterates in
// another order, which reorders BA's sums: equal to rounding, far below
// the synthetic scene's pixel accuracy (0.5 % of the walk).
void CheckSameModel(const Reconstruction& resumed, const Reconstruction& reference) {
  CHECK(resumed.images().size() == reference.images().size());
  CHECK(resumed.NumPoints3D() == reference.NumPoints3D());
  CHECK(resumed.NumObservations() == reference.NumObservations());
  const auto resumed_centers = Centers(resumed);
  const auto reference_centers = Centers(reference);
  REQUIRE(resumed_centers.size() == reference_centers.size());
  for (const auto& [name, center] : reference_centers) {
    INFO(name);
    REQUIRE(resumed_centers.count(name) == 1);
    CHECK((resumed_centers.at(name) - center).norm() <
          1e-6 * SyntheticCaptureOptions().path_length);
  }
  for (const auto& [camera_id, camera] : reference.cameras()) {
    CHECK(resumed.camera(camera_id).MeanFocalLength() ==
          Approx(camera.MeanFocalLength()).epsilon(1e-7));
  }
}

}  // namespace

TEST_CASE("A restored engine continues the model an uninterrupted one builds") {
  const Files& files = Capture();
  const std::size_t n = files.frames.size();
  for (const bool known_intrinsics : {true, false}) {
    INFO("known intrinsics: " << known_intrinsics);
    const std::optional<Camera> camera =
        known_intrinsics ? std::optional<Camera>(files.capture.camera) : std::nullopt;
    // Both ways a checkpoint keeps LSM's windows: cut again from the image
    // files, or written (for images that came as bytes).
    const bool all_windows = !known_intrinsics;
    // Stopped before the model exists (known intrinsics) and while it
    // grows (both; unknown ones still being self-calibrated). The engine
    // is deterministic: the reference's state at a stop is what a run
    // stopped there checkpoints.
    std::vector<std::size_t> stops = {n / 2};
    if (known_intrinsics) stops.insert(stops.begin(), 1);
    struct Stopped {
      Checkpoint checkpoint;
      std::size_t num_registered = 0;
      std::vector<std::string> pending;
      std::vector<image_t> whole;
      std::size_t window_bytes = 0;
    };
    std::vector<Stopped> stopped;
    Engine reference(Engine::Options(), camera);
    std::size_t fed = 0;
    for (const std::size_t stop : stops) {
      Feed(&reference, fed, stop);
      fed = stop;
      stopped.push_back({Save(reference, all_windows),
                         reference.reconstruction().NumRegisteredImages(),
                         reference.PendingImageNames(), reference.lsm_images().WholeImages(),
                         reference.lsm_images().window_bytes()});
    }
    Feed(&reference, fed, n);
    CHECK(reference.reconstruction().NumRegisteredImages() == n);

    for (std::size_t s = 0; s < stops.size(); ++s) {
      const std::size_t stop = stops[s];
      INFO("stopped after " << stop << " images");
      Engine resumed(Engine::Options(), camera);
      Restore(stopped[s].checkpoint, &resumed);
      CHECK(resumed.reconstruction().NumRegisteredImages() == stopped[s].num_registered);
      CHECK(resumed.PendingImageNames() == stopped[s].pending);
      CHECK(resumed.lsm_images().WholeImages() == stopped[s].whole);
      // Windows cut again from the files are cut when LSM first reads them.
      if (all_windows) CHECK(resumed.lsm_images().window_bytes() == stopped[s].window_bytes);
      Feed(&resumed, stop, n);
      CheckSameModel(resumed.reconstruction(), reference.reconstruction());
      if (s + 1 == stops.size()) {
        // Refinement then tries the same pairs, to the same model, as
        // without the restore.
        reference.RefineToEnd();
        resumed.RefineToEnd();
        CHECK(resumed.refinement_totals().num_pairs_tried ==
              reference.refinement_totals().num_pairs_tried);
        CHECK(resumed.refinement_totals().num_pairs_verified ==
              reference.refinement_totals().num_pairs_verified);
        CheckSameModel(resumed.reconstruction(), reference.reconstruction());
      }
    }
  }
}

TEST_CASE("A checkpoint that is cut short, or from another camera, is refused with a reason") {
  const Files& files = Capture();
  // Written once for every section.
  static const Checkpoint checkpoint = [] {
    Engine first(Engine::Options(), Capture().capture.camera);
    Feed(&first, 0, 6);
    return Save(first);
  }();

  SECTION("cut short anywhere") {
    for (const double fraction : {0.0, 0.01, 0.3, 0.7, 0.999}) {
      INFO("cut at " << fraction);
      Checkpoint cut = checkpoint;
      cut.snapshot.resize(std::size_t(fraction * cut.snapshot.size()));
      Engine engine(Engine::Options(), files.capture.camera);
      CHECK_THROWS_AS(Restore(cut, &engine), std::runtime_error);
    }
    Checkpoint cut = checkpoint;
    std::string& record = cut.records.begin()->second;
    record.resize(record.size() / 2);
    Engine engine(Engine::Options(), files.capture.camera);
    CHECK_THROWS_AS(Restore(cut, &engine), std::runtime_error);
  }
  SECTION("a record missing") {
    Checkpoint missing = checkpoint;
    missing.records.erase(missing.records.begin());
    Engine engine(Engine::Options(), files.capture.camera);
    CHECK_THROWS_WITH(Restore(missing, &engine), Catch::Contains("no record of image"));
  }
  SECTION("another camera") {
    Engine engine(Engine::Options(), std::nullopt);
    CHECK_THROWS_WITH(Restore(checkpoint, &engine), Catch::Contains("same --camera"));
  }
  SECTION("missing windows only leave those images out of LSM") {
    Checkpoint without = checkpoint;
    REQUIRE_FALSE(without.windows.empty());
    without.windows.clear();
    Engine engine(Engine::Options(), files.capture.camera);
    Restore(without, &engine);
    CHECK(engine.lsm_images().window_bytes() == 0);
    Feed(&engine, 6, files.frames.size());
    CHECK(engine.reconstruction().NumRegisteredImages() == files.frames.size());
  }
}

}  // namespace flysfm
