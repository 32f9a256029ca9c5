// Engine::Refine: refinement between shots, in slices that give way to a new
// image, on a rendered capture with exact poses.

#include <algorithm>
#include <limits>
#include <map>
#include <memory>
#include <vector>

#include <catch2/catch.hpp>

#include "core/engine.h"
#include "io/evaluation/evaluation.h"
#include "io/synthetic/synthetic_source.h"
#include "tests/testing/rendered_capture.h"

namespace flysfm {
namespace {

using Step = Engine::RefinementSlice::Step;

const SyntheticCapture& Capture() {
  static const SyntheticCapture capture = [] {
    // Few views: each test case runs the whole engine, under the
    // sanitizers too.
    SyntheticCaptureOptions options;
    options.num_views = 8;
    options.seed = 7;
    return testing::RenderedCapture(options);
  }();
  return capture;
}

// Rendered pixels are exact up to interpolation: centres within 0.5 % of
// the walk.
const double kCenterTolerance = 0.005 * SyntheticCaptureOptions().path_length;

double CenterRmse(const Reconstruction& reconstruction) {
  const std::optional<PositionErrors> errors =
      CompareCentersByName(reconstruction, Capture().CameraCentres());
  REQUIRE(errors);
  return errors->rmse;
}

// Arrival stops after two verified pairs, which leaves refinement most of
// the match graph to complete, and refinement matches every pair left,
// whatever the tracks already join.
Engine::Options FewPairsOnArrival() {
  Engine::Options options;
  options.max_verified_pairs = 2;
  options.refinement.max_shared_points = std::numeric_limits<int>::max();
  return options;
}

void AddAll(Engine* engine) {
  for (const Frame& frame : Capture().frames) {
    const std::vector<ImageResult> results = engine->AddImage(frame);
    REQUIRE_FALSE(results.empty());
  }
}

// Slices until there is nothing to do; their steps in order.
std::vector<Engine::RefinementSlice> RefineAll(Engine* engine) {
  std::vector<Engine::RefinementSlice> slices;
  for (int i = 0; i < 10000; ++i) {
    Engine::RefinementSlice slice = engine->Refine();
    if (slice.step == Step::kNone) return slices;
    slices.push_back(std::move(slice));
  }
  FAIL("refinement does not end");
  return slices;
}

// After the model's last snooping, no observation of the images it judged
// is beyond its bound.
std::size_t NumBeyondBounds(const Reconstruction& reconstruction,
                            const OutlierSnooping& snooping) {
  std::size_t beyond = 0;
  for (const auto& [id, point] : reconstruction.points3D()) {
    for (const TrackElement& element : point.track) {
      const auto bound = snooping.max_error_px.find(element.image_id);
      beyond += bound != snooping.max_error_px.end() &&
                reconstruction.ReprojectionError(element.image_id, element.point2D_idx,
                                                 point.xyz) > bound->second;
    }
  }
  return beyond;
}

TEST_CASE("Refinement matches the pairs arrival skipped, then triangulates, adjusts, "
          "retriangulates and snoops, and ends") {
  Engine engine(FewPairsOnArrival(), Capture().camera);
  AddAll(&engine);
  REQUIRE(engine.reconstruction().NumRegisteredImages() == Capture().frames.size());
  const double track_length_before = engine.reconstruction().MeanTrackLength();

  const std::vector<Engine::RefinementSlice> slices = RefineAll(&engine);
  REQUIRE_FALSE(slices.empty());
  // Steps come in the documented order: every match slice first, then the
  // triangulation of the images with new pairs, then the BA and the
  // retriangulation, BA and retriangulation again while they change enough,
  // and last the snooping.
  std::size_t i = 0;
  int tried = 0, verified = 0;
  for (; i < slices.size() && slices[i].step == Step::kMatch; ++i) {
    tried += slices[i].num_pairs_tried;
    verified += slices[i].num_pairs_verified;
    CHECK(slices[i].num_pairs_tried <= engine.options().refinement.pairs_per_slice);
  }
  // 8 images, 28 pairs, all within retrieval's top 30: arrival tried each
  // image's candidates until two verified (at least one each for the 7
  // after the first), refinement tries the rest, each pair once.
  CHECK(tried > 0);
  CHECK(tried <= 28 - 7);
  CHECK(verified > 0);
  REQUIRE(i < slices.size());
  CHECK(slices[i].step == Step::kTriangulate);
  for (; i < slices.size() && slices[i].step == Step::kTriangulate; ++i) {
    CHECK(slices[i].num_images_triangulated <= engine.options().refinement.images_per_slice);
  }
  REQUIRE(i < slices.size());
  int num_adjustments = 0;
  for (; i + 1 < slices.size(); ++i) {
    const Step step = slices[i].step;
    REQUIRE((step == Step::kAdjust || step == Step::kRetriangulate));
    if (step == Step::kAdjust) {
      ++num_adjustments;
      CHECK(slices[i].global_ba);
      CHECK(slices[i].ba.IsSolutionUsable());
      CHECK(slices[i].ba.num_images == int(Capture().frames.size()));
    }
  }
  CHECK(num_adjustments >= 1);
  CHECK(num_adjustments <= engine.options().refinement.max_adjustments);
  CHECK(slices.rbegin()[1].step == Step::kRetriangulate);
  REQUIRE(slices.back().step == Step::kSnoop);
  const OutlierSnooping& snooping = slices.back().snooping;
  // Every image judged (a global BA's model), its noise's 1 % tail dropped
  // and the model adjusted without it.
  CHECK(snooping.max_error_px.size() == Capture().frames.size());
  CHECK(snooping.num_removed > 0);
  CHECK(snooping.summary.IsSolutionUsable());
  REQUIRE(snooping.num_rounds < engine.options().outlier_max_rounds);
  CHECK(NumBeyondBounds(engine.reconstruction(), snooping) == 0);

  // The wider match graph makes longer tracks, and the model stays exact.
  CHECK(engine.reconstruction().MeanTrackLength() > track_length_before);
  CHECK(CenterRmse(engine.reconstruction()) < kCenterTolerance);
  CHECK(engine.reconstruction().MeanReprojectionError() < 0.5);

  const Engine::RefinementTotals& totals = engine.refinement_totals();
  CHECK(totals.num_slices == int(slices.size()));
  CHECK(totals.num_pairs_tried == tried);
  CHECK(totals.num_pairs_verified == verified);
  CHECK(totals.num_pairs_linked == 0);
  CHECK(totals.num_global_bas == num_adjustments);
  CHECK(totals.num_snooped == snooping.num_removed);
  CHECK(totals.ms > 0);

  // Nothing left until a new image.
  CHECK(engine.Refine().step == Step::kNone);
  CHECK(engine.RefineToEnd().empty());
  CHECK(engine.refinement_totals().num_slices == int(slices.size()));

  // Matching changes no track until the triangulation after it: of the same
  // candidates, those whose images share a point are left unmatched when
  // one shared point is enough to call a pair linked.
  Engine::Options linked_options = FewPairsOnArrival();
  linked_options.refinement.max_shared_points = 1;
  Engine linked(linked_options, Capture().camera);
  AddAll(&linked);
  RefineAll(&linked);
  const Engine::RefinementTotals& linked_totals = linked.refinement_totals();
  CHECK(linked_totals.num_pairs_linked > 0);
  CHECK(linked_totals.num_pairs_tried + linked_totals.num_pairs_linked == tried);
  CHECK(linked_totals.num_pairs_verified <= verified);
  CHECK(CenterRmse(linked.reconstruction()) < kCenterTolerance);
}

TEST_CASE("A slice gives way at once when an image waits") {
  Engine engine(FewPairsOnArrival(), Capture().camera);
  AddAll(&engine);
  const auto image_waiting = [] { return true; };
  // One unit of work each: a pair, an image, a BA iteration.
  Engine::RefinementSlice slice = engine.Refine(image_waiting);
  REQUIRE(slice.step == Step::kMatch);
  CHECK(slice.num_pairs_tried == 1);
  // (The last may find no pair left to try.)
  while ((slice = engine.Refine(image_waiting)).step == Step::kMatch) {
    CHECK(slice.num_pairs_tried <= 1);
  }
  REQUIRE(slice.step == Step::kTriangulate);
  CHECK(slice.num_images_triangulated == 1);
  while ((slice = engine.Refine(image_waiting)).step == Step::kTriangulate) {
    CHECK(slice.num_images_triangulated == 1);
  }
  REQUIRE(slice.step == Step::kAdjust);
  CHECK(slice.ba.num_iterations <= 1);
  CHECK(slice.ba.IsSolutionUsable());
  // A BA that gave way is due again.
  CHECK(engine.Refine(image_waiting).step == Step::kAdjust);
  // Left alone, it completes.
  CHECK(engine.Refine().step == Step::kAdjust);
  CHECK(engine.Refine(image_waiting).step == Step::kRetriangulate);
  // So does the snooping, after the retriangulation (and the BAs it makes
  // due, left alone to complete).
  while ((slice = engine.Refine(image_waiting)).step != Step::kSnoop) {
    REQUIRE((slice.step == Step::kRetriangulate || slice.step == Step::kAdjust));
    CHECK(slice.num_images_triangulated <= 1);
    if (slice.step == Step::kAdjust) REQUIRE(engine.Refine().step == Step::kAdjust);
  }
  CHECK(slice.snooping.num_rounds <= 1);
  CHECK(engine.Refine(image_waiting).step == Step::kSnoop);
  CHECK(engine.Refine().step == Step::kSnoop);
  CHECK(engine.Refine().step == Step::kNone);
}

TEST_CASE("A new image starts refinement again, with its own pairs") {
  Engine engine(FewPairsOnArrival(), Capture().camera);
  const std::vector<Frame>& frames = Capture().frames;
  for (std::size_t i = 0; i + 1 < frames.size(); ++i) engine.AddImage(frames[i]);
  RefineAll(&engine);
  REQUIRE(engine.Refine().step == Step::kNone);
  engine.AddImage(frames.back());
  const std::vector<Engine::RefinementSlice> slices = RefineAll(&engine);
  REQUIRE_FALSE(slices.empty());
  CHECK(slices.front().step == Step::kMatch);
  CHECK(slices.front().num_pairs_tried >= 1);
  CHECK(std::any_of(slices.begin(), slices.end(),
                    [](const Engine::RefinementSlice& slice) { return slice.global_ba; }));
}

TEST_CASE("A registration alone makes a global BA due, with no pair left to try") {
  // Arrival tries every pair of 5 images (fewer than max_verified_pairs).
  Engine engine(Engine::Options(), Capture().camera);
  for (std::size_t i = 0; i < 5; ++i) engine.AddImage(Capture().frames[i]);
  REQUIRE(engine.reconstruction().NumRegisteredImages() == 5);
  const std::vector<Engine::RefinementSlice> slices = RefineAll(&engine);
  int tried = 0;
  for (const Engine::RefinementSlice& slice : slices) tried += slice.num_pairs_tried;
  CHECK(tried == 0);
  CHECK(std::any_of(slices.begin(), slices.end(),
                    [](const Engine::RefinementSlice& slice) { return slice.global_ba; }));
}

// A budget of one observation: the block is its minimum, the two images
// registered last.
TEST_CASE("Beyond max_adjusted_observations the BA refines the images registered last, the "
          "rest held") {
  Engine::Options options = FewPairsOnArrival();
  options.refinement.max_adjusted_observations = 1;
  Engine engine(options, Capture().camera);
  AddAll(&engine);
  int num_adjustments = 0;
  const std::vector<Engine::RefinementSlice> slices = RefineAll(&engine);
  for (const Engine::RefinementSlice& slice : slices) {
    if (!slice.global_ba) continue;
    ++num_adjustments;
    CHECK(slice.ba.num_free_images == 2);
    CHECK(slice.ba.num_images > 2);  // held images observing the block's points
    CHECK(slice.ba.IsSolutionUsable());
  }
  CHECK(num_adjustments >= 1);
  // The snooping judges those two alone, and adjusts them alone.
  REQUIRE(slices.back().step == Step::kSnoop);
  const OutlierSnooping& snooping = slices.back().snooping;
  const std::vector<image_t>& registered = engine.reconstruction().RegisteredImageIds();
  CHECK(snooping.max_error_px.size() == 2);
  CHECK(snooping.max_error_px.count(registered.rbegin()[0]) == 1);
  CHECK(snooping.max_error_px.count(registered.rbegin()[1]) == 1);
  if (snooping.num_rounds > 0) CHECK(snooping.summary.num_free_images == 2);
  REQUIRE(snooping.num_rounds < engine.options().outlier_max_rounds);
  CHECK(NumBeyondBounds(engine.reconstruction(), snooping) == 0);
  CHECK(CenterRmse(engine.reconstruction()) < kCenterTolerance);
}

TEST_CASE("Refinement is deterministic for the same images and slices") {
  const auto run = [] {
    auto engine = std::make_unique<Engine>(FewPairsOnArrival(), Capture().camera);
    // Slices between images too, as a paced run gives.
    const std::vector<Frame> frames(Capture().frames.begin(), Capture().frames.begin() + 5);
    for (const Frame& frame : frames) {
      engine->AddImage(frame);
      for (int i = 0; i < 3; ++i) engine->Refine();
    }
    engine->RefineToEnd();
    engine->Finish();
    return engine;
  };
  const std::unique_ptr<Engine> a = run();
  const std::unique_ptr<Engine> b = run();
  REQUIRE(a->reconstruction().NumRegisteredImages() == b->reconstruction().NumRegisteredImages());
  CHECK(a->reconstruction().NumPoints3D() == b->reconstruction().NumPoints3D());
  for (const image_t id : a->reconstruction().RegisteredImageIds()) {
    const Rigid3d& pose_a = *a->reconstruction().image(id).cam_from_world;
    const Rigid3d& pose_b = *b->reconstruction().image(id).cam_from_world;
    CHECK(pose_a.rotation.coeffs() == pose_b.rotation.coeffs());
    CHECK(pose_a.translation == pose_b.translation);
  }
}

TEST_CASE("After refinement ran to its end Finish adjusts nothing more, and without it it does") {
  for (const bool refined : {true, false}) {
    INFO("refined to its end: " << refined);
    Engine engine(Engine::Options(), Capture().camera);
    AddAll(&engine);
    if (refined) engine.RefineToEnd();
    const Reconstruction before = engine.reconstruction();
    bool adjusted = false;
    engine.Finish([&](const Engine::FinishProgress& progress) {
      adjusted |= progress.step != Engine::FinishProgress::Step::kRetry;
    });
    CHECK(adjusted == !refined);
    if (refined) {
      for (const image_t id : before.RegisteredImageIds()) {
        CHECK(engine.reconstruction().image(id).cam_from_world->translation ==
              before.image(id).cam_from_world->translation);
      }
    }
    CHECK(CenterRmse(engine.reconstruction()) < kCenterTolerance);
  }
  // A new image after it makes the end adjust again.
  Engine engine(Engine::Options(), Capture().camera);
  const std::vector<Frame>& frames = Capture().frames;
  for (std::size_t i = 0; i + 1 < frames.size(); ++i) engine.AddImage(frames[i]);
  engine.RefineToEnd();
  engine.AddImage(frames.back());
  bool adjusted = false;
  engine.Finish([&](const Engine::FinishProgress& progress) {
    adjusted |= progress.step != Engine::FinishProgress::Step::kRetry;
  });
  CHECK(adjusted);
}

TEST_CASE("Refinement switched off does nothing") {
  Engine::Options options = FewPairsOnArrival();
  options.refinement.enabled = false;
  Engine engine(options, Capture().camera);
  for (std::size_t i = 0; i < 4; ++i) engine.AddImage(Capture().frames[i]);
  REQUIRE(engine.reconstruction().NumRegisteredImages() == 4);
  CHECK(engine.Refine().step == Step::kNone);
  CHECK(engine.RefineToEnd().empty());
  engine.Finish();
  CHECK(engine.refinement_totals().num_slices == 0);
  CHECK(CenterRmse(engine.reconstruction()) < kCenterTolerance);
}

TEST_CASE("Refinement options are checked") {
  Engine::Options options;
  std::string problem;
  options.refinement.pairs_per_slice = 0;
  CHECK_FALSE(options.Check(&problem));
  CHECK(problem.find("refinement") != std::string::npos);
  options = Engine::Options();
  options.refinement.min_changed_observations = -1;
  CHECK_FALSE(options.Check(&problem));
  options = Engine::Options();
  options.refinement.max_adjusted_observations = 0;
  CHECK_FALSE(options.Check(&problem));
}

}  // namespace
}  // namespace flysfm
