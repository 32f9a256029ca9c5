#include "core/pair_verification.h"

#include <stdexcept>

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

PairVerification PairVerifier::Verify(image_t image_id, const FeatureDescriptors& descriptors,
                                      image_t other_id,
                                      const FeatureDescriptors& other_descriptors,
                                      const std::vector<char>& lsm_refined,
                                      StageTimes* times) const {
  PairVerification pair;
  std::vector<FeatureMatch> raw;
  {
    ScopedStageTimer timer(&times->matching);
    raw = MatchDescriptors(descriptors, other_descriptors, options_.matching);
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
    std::vector<Eigen::Vector2d> other_points, points;
    std::vector<LsmImage> templates;
    std::vector<int> to_refine;
    const int reach = LsmTemplateReach(options_.lsm);
    for (int i = 0; i < int(verified.size()); ++i) {
      if (lsm_refined[verified[i].idx1]) continue;
      to_refine.push_back(i);
      other_points.push_back(other.points2D[verified[i].idx2].xy);
      points.push_back(image.points2D[verified[i].idx1].xy);
      templates.push_back(lsm_images_->Window(other_id, 0, other_points.back(), reach));
    }
    std::vector<char> keep(verified.size(), 1);
    if (!to_refine.empty()) {
      const RefineMatchesResult refined =
          RefineMatches(templates, lsm_images_->SearchPyramid(image_id).front(), other_points,
                        points, options_.lsm);
      for (const int i : to_refine) keep[i] = 0;
      for (const int k : refined.inliers) {
        const int i = to_refine[k];
        keep[i] = 1;
        pair.refined.emplace_back(point2D_t(verified[i].idx1), refined.results[k].point2);
      }
    }
    std::vector<FeatureMatch> kept;
    for (std::size_t i = 0; i < verified.size(); ++i) {
      if (keep[i]) kept.push_back(verified[i]);
    }
    pair.num_lsm_rejected = int(verified.size() - kept.size());
    verified = std::move(kept);
  }
  if (int(verified.size()) >= min_inliers) pair.matches = std::move(verified);
  return pair;
}

}  // namespace flysfm
