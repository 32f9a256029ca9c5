#include "core/pair_verification.h"

#include <stdexcept>

#include "geometry/check.h"
#include "lsm/refine_matches.h"

namespace flysfm {

bool PairVerifier::Options::Check() const {
  return matching.Check() && two_view.Check() && lsm.Check();
}

PairVerifier::PairVerifier(const Options& options, const Reconstruction* reconstruction,
                           LsmImageStore* lsm_images)
    : options_(options), reconstruction_(reconstruction), lsm_images_(lsm_images) {
  if (!options_.Check()) throw std::invalid_argument("invalid pair verification options");
}

PairVerification PairVerifier::Verify(image_t image_id, const FeatureSet& features,
                                      const FeatureDescriptors& root_sift, image_t other_id,
                                      const FeatureSet& other_features,
                                      const std::vector<char>& lsm_refined,
                                      StageTimes* times) const {
  PairVerification pair;
  std::vector<FeatureMatch> raw;
  {
    ScopedStageTimer timer(&times->matching);
    raw = MatchDescriptors(root_sift, RootSift(other_features.descriptors), options_.matching);
  }
  const int min_inliers = options_.two_view.min_num_inliers_f;
  if (int(raw.size()) < min_inliers) return pair;

  const Image& image = reconstruction_->image(image_id);
  const Image& other = reconstruction_->image(other_id);
  std::vector<FeatureMatch> verified;
  {
    ScopedStageTimer timer(&times->verification);
    std::vector<Eigen::Vector2d> points, other_points;
    points.reserve(raw.size());
    other_points.reserve(raw.size());
    for (const FeatureMatch& match : raw) {
      points.push_back(image.points2D[match.idx1].xy);
      other_points.push_back(other.points2D[match.idx2].xy);
    }
    // Always in calibrated form: with unknown intrinsics the guessed camera
    // is a good enough normalisation for E, and GRIC still compares E/F/H.
    pair.geometry = EstimateCalibratedTwoViewGeometry(
        reconstruction_->camera(image.camera_id), points,
        reconstruction_->camera(other.camera_id), other_points, options_.two_view);
    if (pair.geometry.config == TwoViewConfiguration::kDegenerate) return pair;
    for (std::size_t i = 0; i < raw.size(); ++i) {
      if (pair.geometry.inlier_mask[i]) verified.push_back(raw[i]);
    }
  }

  // LSM refines the new image's keypoint on the candidate's window; a match
  // that does not converge is an outlier.
  // An image whose pixels the store dropped leaves the pair unrefined.
  if (options_.lsm_refinement && !verified.empty() && lsm_images_->HasPixels(other_id)) {
    ScopedStageTimer timer(&times->lsm);
    std::vector<FeatureMatch> kept;
    std::vector<LsmImage> search;
    LsmMatcher matcher(options_.lsm);
    const int reach = LsmTemplateReach(options_.lsm);
    for (const FeatureMatch& match : verified) {
      if (lsm_refined[match.idx1]) {
        kept.push_back(match);
        continue;
      }
      if (search.empty()) {
        // The new image is whole while it is matched; a registered one has
        // every keypoint refined already.
        search = lsm_images_->SearchPyramid(image_id);
        FLYSFM_CHECK(!search.empty());
      }
      // Positions are the reconstruction's (the other image's as LSM
      // refined them), scale and orientation SIFT's.
      const Keypoint& other_keypoint = other_features.keypoints[match.idx2];
      const Keypoint& keypoint = features.keypoints[match.idx1];
      const FeatureFrame other_frame{other.points2D[match.idx2].xy, other_keypoint.scale,
                                     other_keypoint.orientation};
      const RefinedMatch refined = RefineMatch(
          [&](int level) { return lsm_images_->Window(other_id, level, other_frame.xy, reach); },
          other_frame, search,
          {image.points2D[match.idx1].xy, keypoint.scale, keypoint.orientation}, &matcher);
      if (!refined.Converged()) continue;
      kept.push_back(match);
      pair.refined.emplace_back(point2D_t(match.idx1), refined.point2);
    }
    pair.num_lsm_rejected = int(verified.size() - kept.size());
    verified = std::move(kept);
  }
  if (int(verified.size()) >= min_inliers) pair.matches = std::move(verified);
  return pair;
}

}  // namespace flysfm
