// Refinement between shots (docs/engine.md, "Refinement between shots"):
// the work COLMAP does with every photo at hand (more pairs matched, tracks
// completed and merged, global BAs with retriangulation), done in slices
// while the engine waits for the next image.

#include <algorithm>
#include <chrono>
#include <unordered_map>

#include "core/engine.h"
#include "core/scene_bundle.h"

namespace flysfm {

bool Engine::Options::Refinement::Check() const {
  return candidates_per_image >= 1 && max_shared_points >= 1 && pairs_per_slice >= 1 &&
         images_per_slice >= 1 &&
         min_changed_observations >= 0 && max_adjustments >= 0 && max_adjusted_observations >= 1;
}

const char* Engine::RefinementStepName(RefinementSlice::Step step) {
  switch (step) {
    case RefinementSlice::Step::kNone: return "nothing left";
    case RefinementSlice::Step::kMatch: return "matching more pairs";
    case RefinementSlice::Step::kTriangulate: return "triangulating new matches";
    case RefinementSlice::Step::kAdjust: return "adjusting";
    case RefinementSlice::Step::kRetriangulate: return "triangulating again";
    case RefinementSlice::Step::kSnoop: return "data snooping";
  }
  return "";
}

Engine::RefinementSlice Engine::Refine(const std::function<bool()>& should_yield) {
  RefinementSlice slice;
  if (!options_.refinement.enabled || !initialized_) return slice;
  const auto start = std::chrono::steady_clock::now();
  RefinementState& state = refinement_;
  if (!state.to_match.empty()) {
    slice.step = RefinementSlice::Step::kMatch;
    MatchMorePairs(should_yield, &slice);
  } else if (!state.to_triangulate.empty()) {
    slice.step = RefinementSlice::Step::kTriangulate;
    TriangulateQueued(&state.to_triangulate, should_yield, &slice);
    if (state.to_triangulate.empty()) slice.registered = RetryWaiting();
    const Triangulator::Summary& added = slice.triangulation;
    if (added.num_new_points + added.num_continued + added.num_completed + added.num_merged >
            0 ||
        !slice.registered.empty()) {
      state.adjust = true;
      state.num_adjustments = 0;
      state.snooped_everything = false;
    }
  } else if (state.adjust) {
    slice.step = RefinementSlice::Step::kAdjust;
    AdjustEverything(should_yield, &slice);
  } else if (!state.to_retriangulate.empty()) {
    slice.step = RefinementSlice::Step::kRetriangulate;
    TriangulateQueued(&state.to_retriangulate, should_yield, &slice);
    state.merged_since_adjust += slice.triangulation.num_merged;
    if (state.to_retriangulate.empty() &&
        state.num_adjustments < options_.refinement.max_adjustments) {
      // Merging moves observations between points without adding any.
      const std::size_t observations = reconstruction_.NumObservations();
      const double changed =
          double(observations > state.observations_after_adjust
                     ? observations - state.observations_after_adjust
                     : state.observations_after_adjust - observations) +
          state.merged_since_adjust;
      state.adjust = changed > options_.refinement.min_changed_observations *
                                   double(std::max<std::size_t>(observations, 1));
    }
  } else if (state.snoop) {
    slice.step = RefinementSlice::Step::kSnoop;
    SnoopEverything(should_yield, &slice);
  }
  for (ImageResult& result : slice.registered) Finalize(&result);
  if (slice.step != RefinementSlice::Step::kNone) {
    RefinementTotals& totals = state.totals;
    ++totals.num_slices;
    totals.num_pairs_tried += slice.num_pairs_tried;
    totals.num_pairs_verified += slice.num_pairs_verified;
    totals.num_pairs_linked += slice.num_pairs_linked;
    totals.num_global_bas += slice.global_ba;
    totals.num_snooped += slice.snooping.num_removed;
    totals.ms +=
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start)
            .count();
  }
  work_seconds_ +=
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return slice;
}

std::vector<ImageResult> Engine::RefineToEnd(
    const std::function<void(const RefinementSlice&)>& on_slice) {
  std::vector<ImageResult> registered;
  for (RefinementSlice slice; (slice = Refine()).step != RefinementSlice::Step::kNone;) {
    if (on_slice) on_slice(slice);
    for (ImageResult& result : slice.registered) registered.push_back(std::move(result));
  }
  return registered;
}

void Engine::MatchMorePairs(const std::function<bool()>& should_yield,
                            RefinementSlice* slice) {
  RefinementState& state = refinement_;
  while (!state.to_match.empty() && slice->num_pairs_tried < options_.refinement.pairs_per_slice) {
    if (slice->num_pairs_tried > 0 && should_yield && should_yield()) return;
    const image_t image_id = state.to_match.front();
    image_t other_id = kInvalidImageId;
    for (const RetrievalCandidate& candidate :
         retriever_.QueryInserted(image_id, options_.refinement.candidates_per_image)) {
      // A restored engine knows the pairs tried on arrival, not those tried
      // here; of these, the verified ones have their matches.
      if (!state.tried_pairs.insert(ImagePairKey(image_id, candidate.image_id)).second ||
          matches_.NumMatches(image_id, candidate.image_id) > 0) {
        continue;
      }
      if (reconstruction_.NumSharedPoints3D(image_id, candidate.image_id) >=
          std::size_t(options_.refinement.max_shared_points)) {
        ++slice->num_pairs_linked;
        continue;
      }
      other_id = candidate.image_id;
      break;
    }
    if (other_id == kInvalidImageId) {
      state.to_match.pop_front();
      continue;
    }
    ++slice->num_pairs_tried;
    // Keypoints of images the model holds stay where LSM put them when
    // each arrived: moving them now would move the points they observe.
    const FeatureSet& features = features_.at(image_id);
    StageTimes times;
    PairVerification pair =
        verifier_.Verify(image_id, features, RootSift(features.descriptors), other_id,
                         features_.at(other_id), std::vector<char>(features.size(), 1), &times);
    if (!pair.verified()) continue;
    ++slice->num_pairs_verified;
    matches_.SetMatches(image_id, other_id, std::move(pair.matches));
    for (const image_t id : {image_id, other_id}) {
      const auto at =
          std::lower_bound(state.to_triangulate.begin(), state.to_triangulate.end(), id);
      if (at == state.to_triangulate.end() || *at != id) state.to_triangulate.insert(at, id);
    }
  }
}

void Engine::TriangulateQueued(std::deque<image_t>* images,
                               const std::function<bool()>& should_yield,
                               RefinementSlice* slice) {
  while (!images->empty() &&
         slice->num_images_triangulated < options_.refinement.images_per_slice) {
    if (slice->num_images_triangulated > 0 && should_yield && should_yield()) return;
    const image_t image_id = images->front();
    images->pop_front();
    if (!reconstruction_.image(image_id).IsRegistered()) continue;
    ++slice->num_images_triangulated;
    slice->triangulation.Add(triangulator_.TriangulateImage(image_id));
    // Pairs matched now may link sub-models, as a new shot's matches do.
    ImageResult linked;
    LinkSubModels(image_id, &linked);
    slice->num_merged_models += linked.num_merged_models;
  }
}

std::unordered_map<image_t, double> Engine::RefinementWindow() const {
  const std::vector<image_t>& registered = reconstruction_.RegisteredImageIds();
  const auto budget = std::size_t(options_.refinement.max_adjusted_observations);
  std::unordered_map<image_t, double> weights;
  std::size_t observations = 0;
  for (auto image = registered.rbegin(); image != registered.rend(); ++image) {
    observations += reconstruction_.image(*image).num_points3D;
    if (weights.size() >= 2 && observations > budget && self_calibrating_.empty()) break;
    weights[*image] = 1.0;
  }
  return weights;
}

void Engine::AdjustEverything(const std::function<bool()>& should_yield,
                              RefinementSlice* slice) {
  RefinementState& state = refinement_;
  BundleAdjuster::Options options = options_.global_ba;
  options.should_stop = should_yield;
  slice->global_ba = true;
  const std::vector<image_t>& registered = reconstruction_.RegisteredImageIds();
  const std::unordered_map<image_t, double> weights = RefinementWindow();
  if (weights.size() == registered.size()) {
    slice->ba = AdjustGlobalBundle(options, &reconstruction_).summary;
  } else {
    // Intrinsics that converged (or were given) stay as they are in a block
    // held by the rest of the model.
    options.refine_focal_length = false;
    options.refine_principal_point = false;
    options.refine_extra_params = false;
    slice->ba = AdjustLocalBundle(weights, options, options_.ba_max_constant_observers,
                                  &reconstruction_)
                    .summary;
  }
  reconstruction_.FilterAllPoints3D(options_.filter_max_error_px,
                                    options_.filter_min_tri_angle_deg);
  // A BA that gave way to a new image runs again, from where it stopped.
  if (should_yield && should_yield()) return;
  state.adjust = false;
  ++state.num_adjustments;
  // Guessed intrinsics that still move would follow the errors the
  // snooping leaves (SnoopOutliers).
  state.snoop = options_.outlier_quantile > 0 && self_calibrating_.empty();
  // Without a snooping to follow, this BA is the end of refinement's work.
  state.snooped_everything =
      !state.snoop && self_calibrating_.empty() && weights.size() == registered.size();
  // A retriangulation that new images interrupted goes on where it stopped,
  // round the model: in a long session every image gets its turn.
  auto first = registered.begin();
  if (!state.to_retriangulate.empty()) {
    first = std::find(registered.begin(), registered.end(), state.to_retriangulate.front());
    if (first == registered.end()) first = registered.begin();
  }
  state.to_retriangulate.assign(first, registered.end());
  state.to_retriangulate.insert(state.to_retriangulate.end(), registered.begin(), first);
  state.observations_after_adjust = reconstruction_.NumObservations();
  state.merged_since_adjust = 0;
}

void Engine::SnoopEverything(const std::function<bool()>& should_yield,
                             RefinementSlice* slice) {
  BundleAdjuster::Options options = options_.global_ba;
  options.should_stop = should_yield;
  // A window of every image has no held observer to bound.
  slice->snooping = SnoopOutliers(RefinementWindow(), options_.ba_max_constant_observers,
                                  options_.outlier_quantile, options_.outlier_max_rounds,
                                  options, options_.filter_min_tri_angle_deg, &reconstruction_);
  // One that gave way to a new image runs again once that image is in.
  if (should_yield && should_yield()) return;
  refinement_.snoop = false;
  refinement_.snooped_everything =
      self_calibrating_.empty() &&
      RefinementWindow().size() == reconstruction_.RegisteredImageIds().size();
}

std::vector<ImageResult> Engine::RetryWaiting() {
  std::vector<ImageResult> results(1);  // a placeholder for "the new image"
  RetryPending(&results);
  results.erase(results.begin());
  return results;
}

}  // namespace flysfm
