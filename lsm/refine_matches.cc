#include "lsm/refine_matches.h"

#include <Eigen/Geometry>

namespace flysfm {

int FeatureLevel(double feature_scale, int window_size, int num_levels) {
  int level = 0;
  while (level + 1 < num_levels &&
         feature_scale >= (2 << level) * kFeatureScalePerWindow * window_size) {
    ++level;
  }
  return level;
}

RefinedMatch RefineMatch(const TemplateOnLevel& template1, const FeatureFrame& feature1,
                         const std::vector<LsmImage>& pyramid2, const FeatureFrame& feature2,
                         LsmMatcher* matcher) {
  RefinedMatch refined;
  if (pyramid2.empty()) return refined;
  const int num_levels = int(pyramid2.size());
  const int window = matcher->options().window_size;
  const int level1 = FeatureLevel(feature1.scale, window, num_levels);
  const int level2 = FeatureLevel(feature2.scale, window, num_levels);
  const double to_level1 = 1.0 / (1 << level1);
  const double to_level2 = 1.0 / (1 << level2);
  // The start of the affine part: the similarity between the two SIFT
  // frames, at the levels' resolutions. From the identity, LSM does not
  // reach a view from twice as near or a camera turned to portrait.
  const double magnify = feature1.scale > 0 && feature2.scale > 0
                             ? feature2.scale / feature1.scale * to_level2 / to_level1
                             : 1.0;
  const Eigen::Matrix2d similarity =
      magnify *
      Eigen::Rotation2Dd(feature2.orientation - feature1.orientation).toRotationMatrix();
  const LsmResult coarse = matcher->Match(template1(level1), to_level1 * feature1.xy,
                                          pyramid2[level2], to_level2 * feature2.xy, similarity);
  refined.status = coarse.status;
  if (!coarse.Converged()) return refined;
  refined.point2 = coarse.point2 / to_level2;
  if (level1 == 0 && level2 == 0) return refined;
  // Full resolution from there sharpens the position. Where its window is
  // too smooth to tell (a blob at that scale), the coarse levels' position
  // stands; where full resolution contradicts the coarse match (it
  // diverges, slides away, or the windows differ), the match is an outlier.
  const LsmResult fine = matcher->Match(template1(0), feature1.xy, pyramid2[0], refined.point2,
                                        coarse.affine * (to_level1 / to_level2));
  if (fine.Converged()) {
    refined.point2 = fine.point2;
  } else if (fine.status != LsmStatus::kLowTexture && fine.status != LsmStatus::kIllConditioned) {
    refined.status = fine.status;
  }
  return refined;
}

}  // namespace flysfm
