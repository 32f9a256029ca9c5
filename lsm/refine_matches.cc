#include "lsm/refine_matches.h"

#include <stdexcept>
#include <string>

namespace flysfm {

namespace {

// `template_for(i)`: the image holding points1[i]'s template.
template <typename TemplateFor>
RefineMatchesResult RefineEach(TemplateFor template_for, const LsmImage& image2,
                               const std::vector<Eigen::Vector2d>& points1,
                               const std::vector<Eigen::Vector2d>& points2,
                               const LsmOptions& options) {
  if (points1.size() != points2.size()) {
    throw std::invalid_argument(
        "RefineMatches: " + std::to_string(points1.size()) +
        " points in image 1 but " + std::to_string(points2.size()) +
        " in image 2");
  }
  LsmMatcher matcher(options);
  RefineMatchesResult refined;
  refined.results.reserve(points1.size());
  for (size_t i = 0; i < points1.size(); ++i) {
    refined.results.push_back(
        matcher.Match(template_for(i), points1[i], image2, points2[i]));
    const LsmStatus status = refined.results.back().status;
    refined.counts.Add(status);
    if (status == LsmStatus::kConverged)
      refined.inliers.push_back(static_cast<int>(i));
  }
  return refined;
}

}  // namespace

RefineMatchesResult RefineMatches(const LsmImage& image1,
                                  const LsmImage& image2,
                                  const std::vector<Eigen::Vector2d>& points1,
                                  const std::vector<Eigen::Vector2d>& points2,
                                  const LsmOptions& options) {
  return RefineEach([&](size_t) -> const LsmImage& { return image1; }, image2,
                    points1, points2, options);
}

RefineMatchesResult RefineMatches(const std::vector<LsmImage>& windows1,
                                  const LsmImage& image2,
                                  const std::vector<Eigen::Vector2d>& points1,
                                  const std::vector<Eigen::Vector2d>& points2,
                                  const LsmOptions& options) {
  if (windows1.size() != points1.size()) {
    throw std::invalid_argument("RefineMatches: " + std::to_string(windows1.size()) +
                                " windows for " + std::to_string(points1.size()) +
                                " points");
  }
  return RefineEach([&](size_t i) -> const LsmImage& { return windows1[i]; },
                    image2, points1, points2, options);
}

RefineMatchesResult RefineMatches(const cv::Mat& image1, const cv::Mat& image2,
                                  const std::vector<Eigen::Vector2d>& points1,
                                  const std::vector<Eigen::Vector2d>& points2,
                                  const LsmOptions& options) {
  return RefineMatches(LsmImage(image1), LsmImage(image2), points1, points2,
                       options);
}

}  // namespace flysfm
