#pragma once

// One candidate pair of the new image (the paper's Fig. 2, "online image
// matching" and "geometric verification"): descriptor matching, two-view
// geometry with GRIC model selection, then LSM refinement of the new image's
// keypoints on the candidate's windows, each on the pyramid level of its
// feature's scale.

#include <optional>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "core/image_result.h"
#include "core/lsm_image_store.h"
#include "core/reconstruction.h"
#include "geometry/two_view_geometry.h"
#include "lsm/lsm.h"
#include "matching/features.h"
#include "matching/matcher.h"

namespace flysfm {

struct PairVerification {
  // Two-view geometry of the raw matches, other_from_image (cam2 = other).
  TwoViewGeometry geometry;
  // The verified matches (image -> other) LSM kept; empty when the pair did
  // not verify.
  std::vector<FeatureMatch> matches;
  // New positions of the new image's keypoints that LSM refined here.
  std::vector<std::pair<point2D_t, Eigen::Vector2d>> refined;
  int num_lsm_rejected = 0;

  bool verified() const { return !matches.empty(); }
};

class PairVerifier {
 public:
  struct Options {
    MatchOptions matching;
    TwoViewGeometryOptions two_view;
    // The paper's LSM refinement; off only for the ablation.
    bool lsm_refinement = true;
    LsmOptions lsm;

    bool Check() const;
  };

  // Reads keypoints and cameras from `reconstruction`, windows from
  // `lsm_images`; both must outlive the verifier.
  PairVerifier(const Options& options, const Reconstruction* reconstruction,
               LsmImageStore* lsm_images);

  // `lsm_refined`: per keypoint of the new image, whether an earlier pair
  // refined it already; such a keypoint keeps its position (it was refined
  // against the more similar candidate) and is not refined again. Adds the
  // matching, verification and LSM times to `times`.
  PairVerification Verify(image_t image_id, const FeatureSet& features, image_t other_id,
                          const FeatureSet& other_features, const std::vector<char>& lsm_refined,
                          StageTimes* times) const;

  // LSM matches each feature on the coarsest of `num_levels` pyramid levels
  // where its SIFT diameter (full-resolution pixels) is at least
  // kFeatureScalePerWindow of the window. A feature SIFT found at a coarse
  // scale is a blob that large; a 15-pixel window on full resolution sees a
  // smooth part of it, too little texture to match (on 6 MP photos, where
  // SIFT keeps the largest scales, most of them), and a view from nearer
  // magnifies it beyond the affine start's reach.
  static constexpr double kFeatureScalePerWindow = 0.4;
  static int FeatureLevel(float feature_scale, int window_size, int num_levels);

 private:
  // The refined position in the new image of the match of the other
  // image's keypoint; nullopt when LSM does not converge on the features'
  // levels. Positions are the reconstruction's (LSM-refined in the other
  // image), the keypoints give scale and orientation.
  std::optional<Eigen::Vector2d> RefineMatch(image_t other_id, const Keypoint& other_keypoint,
                                             const Eigen::Vector2d& other_xy,
                                             const std::vector<LsmImage>& search,
                                             const Keypoint& keypoint, const Eigen::Vector2d& xy,
                                             LsmMatcher* matcher) const;

  Options options_;
  const Reconstruction* reconstruction_;
  LsmImageStore* lsm_images_;
};

}  // namespace flysfm
