#pragma once

// One candidate pair of the new image (the paper's Fig. 2, "online image
// matching" and "geometric verification"): descriptor matching, two-view
// geometry with GRIC model selection, then LSM refinement of the new image's
// keypoints on the candidate's windows, each on the pyramid level of its
// feature's scale.

#include <utility>
#include <vector>

#include <Eigen/Core>

#include "core/scene/image_result.h"
#include "core/lsm_image_store.h"
#include "core/scene/reconstruction.h"
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

  // `root_sift`: RootSift(features.descriptors), which the caller computes
  // once for all the new image's candidates (the candidate's is computed
  // here). `lsm_refined`: per keypoint of the new image, whether an earlier
  // pair refined it already; such a keypoint keeps its position (it was
  // refined against the more similar candidate) and is not refined again.
  // Adds the matching, verification and LSM times to `times`.
  PairVerification Verify(image_t image_id, const FeatureSet& features,
                          const FeatureDescriptors& root_sift, image_t other_id,
                          const FeatureSet& other_features,
                          const std::vector<char>& lsm_refined, StageTimes* times) const;

 private:
  Options options_;
  const Reconstruction* reconstruction_;
  LsmImageStore* lsm_images_;
};

}  // namespace flysfm
