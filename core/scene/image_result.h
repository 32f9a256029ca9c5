#pragma once

// What the engine reports for one image, and the stage timer that fills its
// times so that they add up to the image's total.

#include <chrono>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "geometry/types.h"
#include "geometry/rigid3d.h"

namespace flysfm {

// Milliseconds spent in each stage for one image. Every piece of work the
// engine does for an image lies in exactly one stage, so `total` is their
// sum (decode and features included, wherever they ran).
struct StageTimes {
  double decode = 0;
  double features = 0;
  double retrieval = 0;
  double matching = 0;
  double verification = 0;
  double lsm = 0;
  double registration = 0;
  double triangulation = 0;
  double ba = 0;
  // Sub-models this image linked: the similarity, the merge, and the
  // triangulation and BA around the seam.
  double merge = 0;
  // Tries of waiting images that did not register yet (an image that does
  // register on a retry reports that try's stages in its own result).
  double pending = 0;
  double total = 0;

  // The stages in pipeline order, by name; `total` is not one of them.
  using Stage = std::pair<const char*, double StageTimes::*>;
  static const std::vector<Stage>& Stages();
  // Sets `total` to the sum of the stages.
  void UpdateTotal();
};

// Adds the time from its construction to its destruction to one stage.
// Stages never nest: each timer covers work no other timer covers.
class ScopedStageTimer {
 public:
  explicit ScopedStageTimer(double* stage_ms)
      : stage_ms_(stage_ms), start_(std::chrono::steady_clock::now()) {}
  ~ScopedStageTimer() {
    *stage_ms_ += std::chrono::duration<double, std::milli>(
                      std::chrono::steady_clock::now() - start_)
                      .count();
  }
  ScopedStageTimer(const ScopedStageTimer&) = delete;
  ScopedStageTimer& operator=(const ScopedStageTimer&) = delete;

 private:
  double* stage_ms_;
  std::chrono::steady_clock::time_point start_;
};

enum class ImageStatus {
  kRegistered,
  kPending,   // waits in the pending pool; retried as the model grows
  kRejected,  // unreadable: counted and skipped
};
const char* ImageStatusName(ImageStatus status);

struct ImageResult {
  std::string name;
  image_t image_id = kInvalidImageId;
  ImageStatus status = ImageStatus::kPending;
  // Why the image is pending or rejected; empty when registered.
  std::string reason;
  std::optional<Rigid3d> cam_from_world;
  int num_features = 0;
  int num_candidates = 0;      // retrieved images
  int num_verified_pairs = 0;  // candidates passing two-view geometry and LSM
  int num_lsm_rejected = 0;    // verified matches LSM dropped as outliers
  int num_correspondences = 0; // 2D-3D, before RANSAC (incl. densified)
  int num_densified = 0;       // 2D-3D added by LSM densification
  int num_pose_inliers = 0;
  int num_new_points = 0;      // triangulated with this image
  int num_merged_points = 0;   // points joined with another as one track
  int num_completed = 0;       // observations added to existing tracks
  int num_observations = 0;    // of this image after filtering
  // The local BA: images refined, images held constant, points, iterations.
  int ba_free_images = 0;
  int ba_images = 0;
  int ba_points = 0;
  int ba_iterations = 0;
  // A global BA ran as well (guessed intrinsics converging), and its
  // iterations.
  bool global_ba = false;
  int global_ba_iterations = 0;
  // The focal length (pixels) that the initial pairs' F put in place of a
  // guess far off, with this image (step 6, before any pose).
  std::optional<double> focal_length_from_pairs;
  // The sub-model the image registered in (Reconstruction::Models), and the
  // sub-models it linked and merged into one.
  model_t model_id = kInvalidModelId;
  // Other sub-models the shot was posed in (evidence of a link), and those it
  // linked and merged.
  int num_posed_in_others = 0;
  int num_merged_models = 0;
  // The model after this image: all its sub-models, and how many there are.
  int model_images = 0;
  int model_points = 0;
  int num_models = 0;
  StageTimes times;
};

}  // namespace flysfm
