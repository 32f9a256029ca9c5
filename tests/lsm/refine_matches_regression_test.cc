// LSM refinement on real image pairs: the epipolar consistency of verified
// SIFT matches must improve. Test-only matching: OpenCV SIFT + brute force
// with Lowe's ratio test; the robust F is OpenCV's USAC (both stand in for
// matching/ and geometry/ until those modules land).
#include <algorithm>
#include <cstdio>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include <catch2/catch.hpp>
#include <opencv2/calib3d.hpp>
#include <opencv2/features2d.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "geometry/camera.h"
#include "lsm/refine_matches.h"
#include "tests/testing/data.h"

namespace flysfm {
namespace {

struct Matches {
  std::vector<Eigen::Vector2d> points1;
  std::vector<Eigen::Vector2d> points2;
};

Matches SiftMatches(const cv::Mat& image1, const cv::Mat& image2,
                    int max_features) {
  cv::Ptr<cv::SIFT> sift = cv::SIFT::create(max_features);
  std::vector<cv::KeyPoint> keypoints1, keypoints2;
  cv::Mat descriptors1, descriptors2;
  sift->detectAndCompute(image1, cv::noArray(), keypoints1, descriptors1);
  sift->detectAndCompute(image2, cv::noArray(), keypoints2, descriptors2);
  cv::BFMatcher matcher(cv::NORM_L2);
  std::vector<std::vector<cv::DMatch>> knn;
  matcher.knnMatch(descriptors1, descriptors2, knn, 2);
  Matches matches;
  for (const auto& pair : knn) {
    if (pair.size() < 2 || pair[0].distance > 0.8f * pair[1].distance) continue;
    const cv::Point2f& p1 = keypoints1[pair[0].queryIdx].pt;
    const cv::Point2f& p2 = keypoints2[pair[0].trainIdx].pt;
    matches.points1.emplace_back(p1.x, p1.y);
    matches.points2.emplace_back(p2.x, p2.y);
  }
  return matches;
}

// Undistorted pixel coordinates: the camera's ray through the pixel, seen
// by the same camera without distortion. Epipolar geometry holds there.
std::vector<cv::Point2d> Undistorted(
    const Camera& camera, const std::vector<Eigen::Vector2d>& points) {
  const double fx = camera.params[0];
  const double fy = camera.params[camera.NumFocalParams() - 1];
  const double cx = camera.params[camera.NumFocalParams()];
  const double cy = camera.params[camera.NumFocalParams() + 1];
  std::vector<cv::Point2d> undistorted;
  for (const Eigen::Vector2d& point : points) {
    const Eigen::Vector2d ray = camera.CamFromImg(point);
    undistorted.emplace_back(fx * ray.x() + cx, fy * ray.y() + cy);
  }
  return undistorted;
}

// F by USAC with the threshold in pixels; the inlier mask in `mask`.
cv::Mat RobustFundamental(const std::vector<cv::Point2d>& points1,
                          const std::vector<cv::Point2d>& points2,
                          double threshold_px, std::vector<uchar>* mask) {
  cv::setRNGSeed(1);
  return cv::findFundamentalMat(points1, points2, cv::USAC_ACCURATE,
                                threshold_px, 0.9999, 20000, *mask);
}

double SampsonDistance(const cv::Matx33d& f, const cv::Point2d& p1,
                       const cv::Point2d& p2) {
  const cv::Vec3d x1(p1.x, p1.y, 1.0);
  const cv::Vec3d x2(p2.x, p2.y, 1.0);
  const cv::Vec3d f_x1 = f * x1;
  const cv::Vec3d ft_x2 = f.t() * x2;
  const double numerator = x2.dot(f_x1);
  const double denominator = f_x1[0] * f_x1[0] + f_x1[1] * f_x1[1] +
                             ft_x2[0] * ft_x2[0] + ft_x2[1] * ft_x2[1];
  return std::abs(numerator) / std::sqrt(denominator);
}

// Median Sampson distance (pixels) of a set to the F estimated robustly
// from that same set: least median of squares, the estimator of this very
// figure, free of an inlier threshold.
double MedianSampson(const std::vector<cv::Point2d>& points1,
                     const std::vector<cv::Point2d>& points2) {
  cv::setRNGSeed(1);
  const cv::Mat f = cv::findFundamentalMat(points1, points2, cv::FM_LMEDS, 1.0,
                                           0.9999, 20000);
  REQUIRE(f.rows == 3);
  const cv::Matx33d fundamental(f.ptr<double>());
  std::vector<double> distances;
  for (size_t i = 0; i < points1.size(); ++i) {
    distances.push_back(SampsonDistance(fundamental, points1[i], points2[i]));
  }
  std::nth_element(distances.begin(), distances.begin() + distances.size() / 2,
                   distances.end());
  return distances[distances.size() / 2];
}

template <typename T>
std::vector<T> Select(const std::vector<T>& values,
                      const std::vector<int>& indices) {
  std::vector<T> selected;
  for (const int i : indices) selected.push_back(values[i]);
  return selected;
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
  std::vector<uchar> mask;
  RobustFundamental(Undistorted(camera, matches.points1),
                    Undistorted(camera, matches.points2), 1.5, &mask);
  std::vector<int> verified;
  for (size_t i = 0; i < mask.size(); ++i) {
    if (mask[i]) verified.push_back(static_cast<int>(i));
  }
  const std::vector<Eigen::Vector2d> points1 =
      Select(matches.points1, verified);
  const std::vector<Eigen::Vector2d> points2 =
      Select(matches.points2, verified);
  const RefineMatchesResult refined =
      RefineMatches(image1, image2, points1, points2);

  // Both figures on the matches LSM kept, each against its own F.
  std::vector<Eigen::Vector2d> refined2;
  for (const int i : refined.inliers)
    refined2.push_back(refined.results[i].point2);
  const std::vector<cv::Point2d> kept1 =
      Undistorted(camera, Select(points1, refined.inliers));
  PairFigures figures;
  figures.verified = static_cast<int>(verified.size());
  figures.refined = static_cast<int>(refined.inliers.size());
  if (figures.refined >= 30) {
    figures.raw_median = MedianSampson(
        kept1, Undistorted(camera, Select(points2, refined.inliers)));
    figures.refined_median =
        MedianSampson(kept1, Undistorted(camera, refined2));
  }
  std::string failures;
  for (int s = 1; s < kNumLsmStatus; ++s) {
    const LsmStatus status = static_cast<LsmStatus>(s);
    if (refined.counts[status] == 0) continue;
    failures += std::string(" ") + LsmStatusName(status) + "=" +
                std::to_string(refined.counts[status]);
  }
  std::printf(
      "%-28s verified %4d  refined %4d  median Sampson raw %.4f px  LSM %.4f "
      "px  failures:%s\n",
      name.c_str(), figures.verified, figures.refined, figures.raw_median,
      figures.refined_median, failures.c_str());
  return figures;
}

std::vector<std::string> TumFrames() {
  const std::string folder =
      testing::DataPath("tum/rgbd_dataset_freiburg1_xyz");
  std::ifstream list(folder + "/rgb.txt");
  std::vector<std::string> frames;
  std::string line;
  while (std::getline(list, line)) {
    if (line.empty() || line[0] == '#') continue;
    std::istringstream fields(line);
    std::string timestamp, file;
    fields >> timestamp >> file;
    frames.push_back(folder + "/" + file);
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
