// LSM refinement on real image pairs: the epipolar consistency of verified
// SIFT matches must improve. Matches come from the project's own pipeline
// (matching/: SIFT, mutual ratio-test matching; geometry/: robust F), as the
// engine produces them.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include <catch2/catch.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "geometry/camera.h"
#include "geometry/fundamental_matrix.h"
#include "geometry/two_view_geometry.h"
#include "io/sources/image_source.h"
#include "lsm/refine_matches.h"
#include "matching/features.h"
#include "matching/matcher.h"
#include "tests/testing/data.h"

namespace flysfm {
namespace {

struct Matches {
  std::vector<FeatureFrame> features1;
  std::vector<FeatureFrame> features2;
};

FeatureFrame FrameOf(const Keypoint& keypoint) {
  return {Eigen::Vector2d(keypoint.x, keypoint.y), keypoint.scale, keypoint.orientation};
}

Matches SiftMatches(const cv::Mat& image1, const cv::Mat& image2,
                    int max_features) {
  SiftOptions sift;
  sift.max_num_features = max_features;
  // The images are passed at the resolution LSM works on.
  sift.max_image_size = std::max(image1.cols, image1.rows);
  const FeatureSet features1 = ExtractFeatures(image1, sift);
  const FeatureSet features2 = ExtractFeatures(image2, sift);
  Matches matches;
  for (const FeatureMatch& match : MatchDescriptors(
           RootSift(features1.descriptors), RootSift(features2.descriptors), MatchOptions())) {
    matches.features1.push_back(FrameOf(features1.keypoints[match.idx1]));
    matches.features2.push_back(FrameOf(features2.keypoints[match.idx2]));
  }
  return matches;
}

std::vector<Eigen::Vector2d> Positions(const std::vector<FeatureFrame>& features) {
  std::vector<Eigen::Vector2d> positions;
  for (const FeatureFrame& feature : features) positions.push_back(feature.xy);
  return positions;
}

// Undistorted pixel coordinates: the camera's ray through the pixel, seen
// by the same camera without distortion. Epipolar geometry holds there.
std::vector<Eigen::Vector2d> Undistorted(
    const Camera& camera, const std::vector<Eigen::Vector2d>& points) {
  const double fx = camera.params[0];
  const double fy = camera.params[camera.NumFocalParams() - 1];
  const double cx = camera.params[camera.NumFocalParams()];
  const double cy = camera.params[camera.NumFocalParams() + 1];
  std::vector<Eigen::Vector2d> undistorted;
  for (const Eigen::Vector2d& point : points) {
    const Eigen::Vector2d ray = camera.CamFromImg(point);
    undistorted.emplace_back(fx * ray.x() + cx, fy * ray.y() + cy);
  }
  return undistorted;
}

// F by the project's RANSAC (MSAC, LO, least-squares refinement), the
// threshold on the Sampson distance in pixels; fixed seed.
RansacResult<Eigen::Matrix3d> RobustFundamental(
    const std::vector<Eigen::Vector2d>& points1,
    const std::vector<Eigen::Vector2d>& points2, double threshold_px) {
  RansacOptions ransac;
  ransac.max_error = threshold_px;
  ransac.confidence = 0.9999;
  ransac.max_iterations = 20000;
  ransac.seed = 1;
  return EstimateFundamentalMatrix(points1, points2, ransac);
}

// Median Sampson distance (pixels) of a set to the F estimated robustly
// from that same set. The 1 px threshold lies well above the residuals of
// true SIFT matches (a few tenths of a pixel) and below gross errors, for
// the raw and the refined set alike.
double MedianSampson(const std::vector<Eigen::Vector2d>& points1,
                     const std::vector<Eigen::Vector2d>& points2) {
  const RansacResult<Eigen::Matrix3d> f =
      RobustFundamental(points1, points2, 1.0);
  REQUIRE(f.success);
  std::vector<double> distances;
  for (size_t i = 0; i < points1.size(); ++i) {
    distances.push_back(
        std::sqrt(FundamentalSampsonError(f.model, points1[i], points2[i])));
  }
  std::nth_element(distances.begin(), distances.begin() + distances.size() / 2,
                   distances.end());
  return distances[distances.size() / 2];
}

struct PairFigures {
  int verified = 0;
  int refined = 0;
  double raw_median = 0.0;
  double refined_median = 0.0;
};

PairFigures EvaluatePair(const cv::Mat& image1, const cv::Mat& image2,
                         const Camera& camera, int max_features,
                         const std::string& name) {
  const Matches matches = SiftMatches(image1, image2, max_features);
  // Verified matches: inliers of a robust F on the raw SIFT positions.
  const RansacResult<Eigen::Matrix3d> verification =
      RobustFundamental(Undistorted(camera, Positions(matches.features1)),
                        Undistorted(camera, Positions(matches.features2)), 1.5);
  REQUIRE(verification.success);
  const std::vector<LsmImage> pyramid1 = BuildLsmPyramid(image1, 3);
  const std::vector<LsmImage> pyramid2 = BuildLsmPyramid(image2, 3);
  LsmMatcher matcher{LsmOptions()};
  PairFigures figures;
  std::vector<Eigen::Vector2d> kept1, raw2, refined2;
  LsmStatusCounts counts;
  for (size_t i = 0; i < verification.inlier_mask.size(); ++i) {
    if (!verification.inlier_mask[i]) continue;
    ++figures.verified;
    const RefinedMatch refined =
        RefineMatch([&](int level) { return pyramid1[level]; }, matches.features1[i], pyramid2,
                    matches.features2[i], &matcher);
    counts.Add(refined.status);
    if (!refined.Converged()) continue;
    kept1.push_back(matches.features1[i].xy);
    raw2.push_back(matches.features2[i].xy);
    refined2.push_back(refined.point2);
  }

  // Both figures on the matches LSM kept, each against its own F.
  figures.refined = static_cast<int>(kept1.size());
  if (figures.refined >= 30) {
    kept1 = Undistorted(camera, kept1);
    figures.raw_median = MedianSampson(kept1, Undistorted(camera, raw2));
    figures.refined_median = MedianSampson(kept1, Undistorted(camera, refined2));
  }
  std::string failures;
  for (int s = 1; s < kNumLsmStatus; ++s) {
    const LsmStatus status = static_cast<LsmStatus>(s);
    if (counts[status] == 0) continue;
    failures += std::string(" ") + LsmStatusName(status) + "=" +
                std::to_string(counts[status]);
  }
  std::printf(
      "%-28s verified %4d  refined %4d  median Sampson raw %.4f px  LSM %.4f "
      "px  failures:%s\n",
      name.c_str(), figures.verified, figures.refined, figures.raw_median,
      figures.refined_median, failures.c_str());
  return figures;
}

std::vector<std::string> TumFrames() {
  std::vector<std::string> frames;
  for (const Frame& frame :
       ListTumSequence(testing::DataPath("tum/rgbd_dataset_freiburg1_xyz"))) {
    frames.push_back(frame.path.string());
  }
  return frames;
}

cv::Mat ReadGrey(const std::string& path) {
  cv::Mat image = cv::imread(path, cv::IMREAD_GRAYSCALE);
  INFO(path);
  REQUIRE(!image.empty());
  return image;
}

TEST_CASE("LSM lowers the Sampson error of verified SIFT matches",
          "[regression]") {
  int pairs = 0;

  // TUM fr1_xyz, its published calibration; frames a third of a second
  // apart.
  const Camera tum = Camera::FromString(
      "FULL_OPENCV 517.3,516.5,318.6,255.3,0.2624,-0.9531,-0.0054,0.0026,"
      "1.1633,0,0,0",
      640, 480);
  const std::vector<std::string> frames = TumFrames();
  REQUIRE(frames.size() >= 300);
  for (int first = 0; first + 10 < 300; first += 50) {
    const PairFigures figures = EvaluatePair(
        ReadGrey(frames[first]), ReadGrey(frames[first + 10]), tum, 4000,
        "tum " + std::to_string(first) + "-" + std::to_string(first + 10));
    INFO("tum pair from frame " << first);
    REQUIRE(figures.refined >= 30);
    CHECK(figures.refined_median < figures.raw_median);
    ++pairs;
  }

  // fountain-P11 at half resolution: images/K.txt halved, no distortion.
  const std::string fountain =
      testing::DataPath("strecha/fountain-P11/images/");
  const Camera half =
      Camera::FromString("PINHOLE 1379.74,1382.08,760.6,503.2", 1536, 1024);
  for (int first = 0; first + 1 < 10; first += 2) {
    char name1[16], name2[16];
    std::snprintf(name1, sizeof(name1), "%04d.jpg", first);
    std::snprintf(name2, sizeof(name2), "%04d.jpg", first + 1);
    cv::Mat image1, image2;
    cv::resize(ReadGrey(fountain + name1), image1, cv::Size(1536, 1024), 0, 0,
               cv::INTER_AREA);
    cv::resize(ReadGrey(fountain + name2), image2, cv::Size(1536, 1024), 0, 0,
               cv::INTER_AREA);
    const PairFigures figures =
        EvaluatePair(image1, image2, half, 6000,
                     std::string("fountain ") + name1 + "-" + name2);
    INFO("fountain pair " << name1);
    REQUIRE(figures.refined >= 30);
    CHECK(figures.refined_median < figures.raw_median);
    ++pairs;
  }
  CHECK(pairs >= 10);
}

}  // namespace
}  // namespace flysfm
