#include "core/pair_verification.h"

#include <stdexcept>

#include <Eigen/Geometry>

#include "geometry/check.h"

namespace flysfm {

bool PairVerifier::Options::Check() const {
  return matching.Check() && two_view.Check() && lsm.Check();
}

PairVerifier::PairVerifier(const Options& options, const Reconstruction* reconstruction,
                           LsmImageStore* lsm_images)
    : options_(options), reconstruction_(reconstruction), lsm_images_(lsm_images) {
  if (!options_.Check()) throw std::invalid_argument("invalid pair verification options");
}

int PairVerifier::FeatureLevel(float feature_scale, int window_size, int num_levels) {
  int level = 0;
  while (level + 1 < num_levels &&
         feature_scale >= (2 << level) * kFeatureScalePerWindow * window_size) {
    ++level;
  }
  return level;
}

std::optional<Eigen::Vector2d> PairVerifier::RefineMatch(image_t other_id,
                                                         const Keypoint& other_keypoint,
                                                         const Eigen::Vector2d& other_xy,
                                                         const std::vector<LsmImage>& search,
                                                         const Keypoint& keypoint,
                                                         const Eigen::Vector2d& xy,
                                                         LsmMatcher* matcher) const {
  const int reach = LsmTemplateReach(options_.lsm);
  const int num_levels = int(search.size());
  const int window = options_.lsm.window_size;
  const int other_level = FeatureLevel(other_keypoint.scale, window, num_levels);
  const int level = FeatureLevel(keypoint.scale, window, num_levels);
  const double other_to_level = 1.0 / (1 << other_level);
  const double to_level = 1.0 / (1 << level);
  // The start of the affine part: the similarity between the two SIFT
  // frames, at the levels' resolutions. From the identity, LSM does not
  // reach a view from twice as near or a camera turned to portrait.
  const double turn = double(keypoint.orientation) - other_keypoint.orientation;
  const double magnify =
      other_keypoint.scale > 0 ? keypoint.scale / other_keypoint.scale * to_level / other_to_level
                               : 1.0;
  const Eigen::Matrix2d similarity =
      magnify * Eigen::Rotation2Dd(turn).toRotationMatrix();
  const LsmResult coarse =
      matcher->Match(lsm_images_->Window(other_id, other_level, other_xy, reach),
                     other_to_level * other_xy, search[level], to_level * xy, similarity);
  if (!coarse.Converged()) return std::nullopt;
  const Eigen::Vector2d refined = coarse.point2 / to_level;
  if (level == 0 && other_level == 0) return refined;
  // Full resolution from there sharpens the position where the finer
  // texture allows; where it does not (a smooth blob at that scale), the
  // coarse levels' position stands.
  const LsmResult fine =
      matcher->Match(lsm_images_->Window(other_id, 0, other_xy, reach), other_xy, search[0],
                     refined, coarse.affine * (other_to_level / to_level));
  return fine.Converged() ? fine.point2 : refined;
}

PairVerification PairVerifier::Verify(image_t image_id, const FeatureSet& features,
                                      image_t other_id, const FeatureSet& other_features,
                                      const std::vector<char>& lsm_refined,
                                      StageTimes* times) const {
  PairVerification pair;
  std::vector<FeatureMatch> raw;
  {
    ScopedStageTimer timer(&times->matching);
    raw = MatchDescriptors(features.descriptors, other_features.descriptors, options_.matching);
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
      const std::optional<Eigen::Vector2d> xy = RefineMatch(
          other_id, other_features.keypoints[match.idx2], other.points2D[match.idx2].xy, search,
          features.keypoints[match.idx1], image.points2D[match.idx1].xy, &matcher);
      if (!xy) continue;
      kept.push_back(match);
      pair.refined.emplace_back(point2D_t(match.idx1), *xy);
    }
    pair.num_lsm_rejected = int(verified.size() - kept.size());
    verified = std::move(kept);
  }
  if (int(verified.size()) >= min_inliers) pair.matches = std::move(verified);
  return pair;
}

}  // namespace flysfm
