#include "matching/features.h"

#include <algorithm>
#include <sstream>
#include <stdexcept>
#include <set>
#include <vector>

#include <catch2/catch.hpp>
#include <opencv2/features2d.hpp>
#include <opencv2/imgproc.hpp>

#include "io/synthetic/procedural_texture.h"
#include "matching/matcher.h"
#include "tests/testing/warped_pair.h"

namespace flysfm {
namespace {

// Median distance between the position of each match in image 2 and the
// homography's image of its position in image 1.
double MedianWarpError(const FeatureSet& f1, const FeatureSet& f2,
                       const std::vector<FeatureMatch>& matches, const Eigen::Matrix3d& h) {
  std::vector<double> errors;
  for (const FeatureMatch& m : matches) {
    const Keypoint &a = f1.keypoints[m.idx1], &b = f2.keypoints[m.idx2];
    const Eigen::Vector2d predicted = testing::ApplyHomography(h, Eigen::Vector2d(a.x, a.y));
    errors.push_back((predicted - Eigen::Vector2d(b.x, b.y)).norm());
  }
  std::nth_element(errors.begin(), errors.begin() + errors.size() / 2, errors.end());
  return errors[errors.size() / 2];
}

TEST_CASE("SIFT matches on a warped texture agree with the warp") {
  const testing::WarpedPair pair = testing::MakeWarpedPair(640, 480, 12.0, 0.9, 640, 480, 7);
  const FeatureSet f1 = ExtractFeatures(pair.image1, SiftOptions());
  const FeatureSet f2 = ExtractFeatures(pair.image2, SiftOptions());
  const std::vector<FeatureMatch> matches =
      MatchDescriptors(RootSift(f1.descriptors), RootSift(f2.descriptors), {});
  REQUIRE(matches.size() >= 200);
  CHECK(MedianWarpError(f1, f2, matches, pair.homography) < 0.5);
}

TEST_CASE("keypoints of a downscaled extraction are in full-resolution pixels") {
  // Image 2 is twice as large as image 1 and extracted at half size: its
  // keypoints must still land where the warp puts them, in full resolution
  // (within 0.5 px at extraction scale, i.e. 1 px at full scale).
  const testing::WarpedPair pair = testing::MakeWarpedPair(640, 480, 5.0, 2.0, 1400, 1000, 3);
  SiftOptions small;
  small.max_image_size = 700;
  const FeatureSet f1 = ExtractFeatures(pair.image1, SiftOptions());
  const FeatureSet f2 = ExtractFeatures(pair.image2, small);
  CHECK(f2.width == 1400);
  CHECK(f2.height == 1000);
  const std::vector<FeatureMatch> matches =
      MatchDescriptors(RootSift(f1.descriptors), RootSift(f2.descriptors), {});
  REQUIRE(matches.size() >= 200);
  CHECK(MedianWarpError(f1, f2, matches, pair.homography) < 1.0);
  for (const Keypoint& kp : f2.keypoints) {
    REQUIRE(kp.x >= -0.5f);
    REQUIRE(kp.x <= 1399.5f);
  }
}

TEST_CASE("descriptors are OpenCV's SIFT bytes, their RootSIFT unit vectors, the count capped") {
  SiftOptions options;
  options.max_num_features = 500;
  const cv::Mat texture = MakeTexture(640, 480, 1);
  const FeatureSet f = ExtractFeatures(texture, options);
  REQUIRE(f.size() == 500);
  CHECK(f.descriptors.rows() == f.size());
  const FeatureDescriptors root = RootSift(f.descriptors);
  for (int i = 0; i < f.size(); ++i) {
    REQUIRE(root.row(i).norm() == Approx(1.0).margin(1e-4));
    REQUIRE(root.row(i).minCoeff() >= 0.f);
  }
  // OpenCV's float descriptors are whole numbers 0-255, which the bytes hold
  // exactly: every one of the kept ones is among them.
  REQUIRE(texture.type() == CV_8UC1);
  std::vector<cv::KeyPoint> keypoints;
  cv::Mat opencv;
  cv::SIFT::create()->detectAndCompute(texture, cv::noArray(), keypoints, opencv);
  int whole = 0;
  for (int r = 0; r < opencv.rows; ++r) {
    for (int c = 0; c < 128; ++c) whole += opencv.at<float>(r, c) == std::round(opencv.at<float>(r, c));
  }
  CHECK(whole == opencv.rows * 128);
  std::set<std::vector<std::uint8_t>> from_opencv;
  for (int r = 0; r < opencv.rows; ++r) {
    std::vector<std::uint8_t> row(128);
    for (int c = 0; c < 128; ++c) row[c] = std::uint8_t(opencv.at<float>(r, c));
    from_opencv.insert(row);
  }
  for (int i = 0; i < f.size(); ++i) {
    const std::vector<std::uint8_t> row(f.descriptors.row(i).data(),
                                        f.descriptors.row(i).data() + 128);
    REQUIRE(from_opencv.count(row) == 1);
  }
}

TEST_CASE("the cap keeps a share of the largest-scale keypoints, the rest the strongest") {
  SiftOptions options;
  options.max_num_features = 1 << 20;
  const cv::Mat texture = MakeTexture(640, 480, 3);
  const FeatureSet all = ExtractFeatures(texture, options);
  options.max_num_features = 300;
  REQUIRE(all.size() > 2 * options.max_num_features);
  std::vector<float> scales;
  for (const Keypoint& kp : all.keypoints) scales.push_back(kp.scale);
  std::sort(scales.rbegin(), scales.rend());
  const auto num_at_least = [](const FeatureSet& f, float scale) {
    return std::count_if(f.keypoints.begin(), f.keypoints.end(),
                         [&](const Keypoint& kp) { return kp.scale >= scale; });
  };
  for (const double share : {0.0, 1.0 / 3.0, 1.0}) {
    options.large_scale_share = share;
    const FeatureSet kept = ExtractFeatures(texture, options);
    REQUIRE(kept.size() == options.max_num_features);
    const int num_large = int(std::lround(share * options.max_num_features));
    if (num_large > 0) CHECK(num_at_least(kept, scales[num_large - 1]) >= num_large);
    for (const Keypoint& kp : kept.keypoints) {
      // The same detection, only fewer of them.
      REQUIRE(std::any_of(all.keypoints.begin(), all.keypoints.end(), [&](const Keypoint& other) {
        return other.x == kp.x && other.y == kp.y && other.scale == kp.scale;
      }));
    }
  }
}

TEST_CASE("keypoints carry the colour of their pixel in RGB order") {
  // Texture in green only, red saturated, blue zero: whatever the keypoint,
  // r = 255 and b = 0, and g is the pixel's green value.
  const cv::Mat texture = MakeTexture(320, 240, 5);
  cv::Mat bgr;
  cv::merge(std::vector<cv::Mat>{cv::Mat::zeros(240, 320, CV_8U), texture,
                                 cv::Mat(240, 320, CV_8U, cv::Scalar(255))},
            bgr);
  const FeatureSet f = ExtractFeatures(bgr, SiftOptions());
  REQUIRE(f.size() > 50);
  for (const Keypoint& kp : f.keypoints) {
    REQUIRE(kp.r == 255);
    REQUIRE(kp.b == 0);
    REQUIRE(kp.g == texture.at<std::uint8_t>(int(std::lround(kp.y)), int(std::lround(kp.x))));
  }
}

TEST_CASE("a blank image has no features and bad images or options are rejected") {
  CHECK(ExtractFeatures(cv::Mat(240, 320, CV_8U, cv::Scalar(90)), SiftOptions()).size() == 0);
  CHECK_THROWS_AS(ExtractFeatures(cv::Mat(), SiftOptions()), std::invalid_argument);
  CHECK_THROWS_AS(ExtractFeatures(cv::Mat(10, 10, CV_32F, cv::Scalar(0)), SiftOptions()),
                  std::invalid_argument);
  SiftOptions bad;
  bad.max_num_features = 0;
  CHECK_FALSE(bad.Check());
  SiftOptions bad_share;
  bad_share.large_scale_share = 1.5;
  CHECK_FALSE(bad_share.Check());
  CHECK_THROWS_AS(ExtractFeatures(MakeTexture(64, 64, 1), bad), std::invalid_argument);
}

TEST_CASE("with the grey image given, extraction is the same, and a wrong grey is rejected") {
  const cv::Mat image = MakeTexture(320, 240, 7, true);
  cv::Mat grey;
  cv::cvtColor(image, grey, cv::COLOR_BGR2GRAY);
  const FeatureSet own = ExtractFeatures(image, SiftOptions());
  const FeatureSet given = ExtractFeatures(image, grey, SiftOptions());
  REQUIRE(given.size() == own.size());
  CHECK(given.descriptors == own.descriptors);
  for (int i = 0; i < own.size(); ++i) {
    CHECK(given.keypoints[i].x == own.keypoints[i].x);
    CHECK(given.keypoints[i].r == own.keypoints[i].r);
  }
  CHECK_THROWS_AS(ExtractFeatures(image, image, SiftOptions()), std::invalid_argument);
  CHECK_THROWS_AS(ExtractFeatures(image, cv::Mat(10, 10, CV_8U), SiftOptions()),
                  std::invalid_argument);
  CHECK_THROWS_AS(ExtractFeatures(cv::Mat(80, 107, CV_8UC3), grey, SiftOptions()),
                  std::invalid_argument);  // 320 / 107: no reduction of 2, 4 or 8
}

TEST_CASE("colours come from a reduced colour image, the features from the full grey") {
  // Blue and green constant over 4 x 4 blocks, so a block's average is each
  // of its pixels' colour.
  const cv::Mat texture = MakeTexture(322, 242, 8);
  const cv::Mat reduced = MakeTexture(81, 61, 9);
  cv::Mat blocks;
  cv::resize(reduced, blocks, cv::Size(324, 244), 0, 0, cv::INTER_NEAREST);
  blocks = blocks(cv::Rect(0, 0, 322, 242)).clone();
  cv::Mat bgr;
  cv::merge(std::vector<cv::Mat>{blocks, 255 - blocks, texture}, bgr);
  cv::Mat reduced_bgr;
  cv::merge(std::vector<cv::Mat>{reduced, 255 - reduced, cv::Mat(61, 81, CV_8U, cv::Scalar(0))},
            reduced_bgr);
  const FeatureSet full = ExtractFeatures(bgr, texture, SiftOptions());
  const FeatureSet from_reduced = ExtractFeatures(reduced_bgr, texture, SiftOptions());
  REQUIRE(full.size() > 50);
  REQUIRE(from_reduced.size() == full.size());
  CHECK(from_reduced.descriptors == full.descriptors);
  for (int i = 0; i < full.size(); ++i) {
    REQUIRE(from_reduced.keypoints[i].x == full.keypoints[i].x);
    REQUIRE(from_reduced.keypoints[i].b == full.keypoints[i].b);
    REQUIRE(from_reduced.keypoints[i].g == full.keypoints[i].g);
  }
}

}  // namespace
}  // namespace flysfm

namespace flysfm {

TEST_CASE("a feature set written and read back is identical, a cut one is refused") {
  const FeatureSet features = ExtractFeatures(MakeTexture(320, 240, 3), SiftOptions());
  REQUIRE(features.size() > 0);
  std::stringstream stream;
  WriteFeatureSet(stream, features);
  const FeatureSet read = ReadFeatureSet(stream);
  CHECK(read.width == features.width);
  CHECK(read.height == features.height);
  REQUIRE(read.size() == features.size());
  for (int i = 0; i < features.size(); ++i) {
    CHECK(read.keypoints[i].x == features.keypoints[i].x);
    CHECK(read.keypoints[i].scale == features.keypoints[i].scale);
    CHECK(read.keypoints[i].g == features.keypoints[i].g);
  }
  CHECK(read.descriptors == features.descriptors);
  const std::string bytes = stream.str();
  std::istringstream cut(bytes.substr(0, bytes.size() - 1));
  CHECK_THROWS_AS(ReadFeatureSet(cut), std::runtime_error);
}

}  // namespace flysfm
