#include "matching/features.h"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <stdexcept>

#include <opencv2/features2d.hpp>
#include <opencv2/imgproc.hpp>

#include "geometry/binary_io.h"
#include "geometry/check.h"
#include "matching/image_decode.h"

namespace flysfm {

bool SiftOptions::Check() const {
  return max_num_features > 0 && large_scale_share >= 0 && large_scale_share <= 1 &&
         max_image_size >= 16 && peak_threshold >= 0 &&
         edge_threshold > 0 && num_octave_layers >= 1;
}

void RootSiftInPlace(FeatureDescriptors* descriptors) {
  for (Eigen::Index i = 0; i < descriptors->rows(); ++i) {
    auto row = descriptors->row(i);
    const float l1 = row.cwiseAbs().sum();
    if (l1 > 0.f) row = (row.cwiseAbs() / l1).cwiseSqrt();
  }
}

FeatureDescriptors RootSift(const SiftDescriptors& sift) {
  FeatureDescriptors root = sift.cast<float>();
  RootSiftInPlace(&root);
  return root;
}

namespace {

// Of `max_num_features`, a share `large_scale_share` goes to the largest
// scales, the rest to the strongest DoG responses among the others. OpenCV
// keeps the strongest responses only, which on photos are mostly the finest
// scales: brick joints, foliage, the doubled octave's noise, which another
// viewpoint does not repeat. Coarse blobs repeat across views (COLMAP keeps
// the largest scales only); fine strong features are the precise ones.
// Ties are broken by position, so the selection does not depend on the
// detector's order. Returns the kept keypoints' indices: all in the
// detector's order, or the selection largest first.
std::vector<int> SelectKeypoints(int max_num_features, double large_scale_share,
                                 const std::vector<cv::KeyPoint>& keypoints) {
  std::vector<int> kept(keypoints.size());
  std::iota(kept.begin(), kept.end(), 0);
  const auto by_position = [&](int a, int b) {
    const cv::KeyPoint& ka = keypoints[a];
    const cv::KeyPoint& kb = keypoints[b];
    return ka.pt.y != kb.pt.y ? ka.pt.y < kb.pt.y : ka.pt.x < kb.pt.x;
  };
  const auto larger = [&](int a, int b) {
    const cv::KeyPoint& ka = keypoints[a];
    const cv::KeyPoint& kb = keypoints[b];
    if (ka.size != kb.size) return ka.size > kb.size;
    if (ka.response != kb.response) return ka.response > kb.response;
    return by_position(a, b);
  };
  const auto stronger = [&](int a, int b) {
    const cv::KeyPoint& ka = keypoints[a];
    const cv::KeyPoint& kb = keypoints[b];
    if (ka.response != kb.response) return ka.response > kb.response;
    if (ka.size != kb.size) return ka.size > kb.size;
    return by_position(a, b);
  };
  if (int(kept.size()) <= max_num_features) return kept;
  const auto begin = kept.begin();
  const int num_large = int(std::lround(large_scale_share * max_num_features));
  std::nth_element(begin, begin + num_large, kept.end(), larger);
  std::nth_element(begin + num_large, begin + max_num_features, kept.end(), stronger);
  kept.resize(max_num_features);
  std::sort(kept.begin(), kept.end(), larger);
  return kept;
}

}  // namespace

FeatureSet ExtractFeatures(const cv::Mat& image, const SiftOptions& options) {
  if (image.empty() || image.depth() != CV_8U || image.channels() != 3) {
    return ExtractFeatures(image, image, options);
  }
  cv::Mat grey;
  cv::cvtColor(image, grey, cv::COLOR_BGR2GRAY);
  return ExtractFeatures(image, grey, options);
}

FeatureSet ExtractFeatures(const cv::Mat& colour, cv::Mat grey, const SiftOptions& options) {
  if (!options.Check()) throw std::invalid_argument("invalid SiftOptions");
  if (colour.empty()) throw std::invalid_argument("ExtractFeatures: empty image");
  if (colour.depth() != CV_8U || (colour.channels() != 1 && colour.channels() != 3)) {
    throw std::invalid_argument("ExtractFeatures: need an 8-bit grey or BGR image");
  }
  if (grey.type() != CV_8UC1) {
    throw std::invalid_argument("ExtractFeatures: `grey` must be the image in 8-bit grey");
  }
  const int reduction = std::max(1, int(std::lround(double(grey.cols) / colour.cols)));
  if ((reduction != 1 && reduction != 2 && reduction != 4 && reduction != 8) ||
      colour.size() != DctReducedSize(grey.size(), reduction)) {
    throw std::invalid_argument(
        "ExtractFeatures: the colour image must be `grey`'s size or reduced by 2, 4 or 8");
  }
  const int width = grey.cols;
  const int height = grey.rows;
  const int long_side = std::max(width, height);
  double scale = 1.0;  // full resolution / extraction resolution
  if (long_side > options.max_image_size) {
    scale = double(long_side) / options.max_image_size;
    cv::Mat small;
    cv::resize(grey, small,
               cv::Size(std::max(1, int(std::lround(width / scale))),
                        std::max(1, int(std::lround(height / scale)))),
               0, 0, cv::INTER_AREA);
    grey = small;
  }
  const double scale_x = double(width) / grey.cols;
  const double scale_y = double(height) / grey.rows;

  cv::Ptr<cv::SIFT> sift = cv::SIFT::create(0, options.num_octave_layers,
                                             options.peak_threshold, options.edge_threshold);
  std::vector<cv::KeyPoint> cv_keypoints;
  cv::Mat cv_descriptors;
  // Describing every keypoint found costs less than building the pyramid a
  // second time to describe the kept ones only (fr1_xyz frame: 52 ms instead
  // of 67; fountain-P11 photo at 1 600 px: 239 instead of 323).
  sift->detectAndCompute(grey, cv::noArray(), cv_keypoints, cv_descriptors);
  FLYSFM_CHECK(cv_descriptors.empty() ||
               (cv_descriptors.rows == int(cv_keypoints.size()) &&
                cv_descriptors.cols == 128 && cv_descriptors.type() == CV_32F));
  const std::vector<int> kept =
      SelectKeypoints(options.max_num_features, options.large_scale_share, cv_keypoints);

  FeatureSet features;
  features.width = width;
  features.height = height;
  const int n = static_cast<int>(kept.size());
  features.keypoints.resize(n);
  features.descriptors.resize(n, 128);
  for (int i = 0; i < n; ++i) {
    const cv::KeyPoint& kp = cv_keypoints[kept[i]];
    Keypoint& out = features.keypoints[i];
    // Pixel centres map as (x + 0.5) * s - 0.5 between resolutions.
    out.x = float((kp.pt.x + 0.5) * scale_x - 0.5);
    out.y = float((kp.pt.y + 0.5) * scale_y - 0.5);
    out.scale = float(kp.size * scale);
    out.orientation = float(kp.angle * M_PI / 180.0);
    // A reduced pixel i covers full pixels [i r, i r + r).
    const int px = std::clamp(int(std::floor((out.x + 0.5) / reduction)), 0, colour.cols - 1);
    const int py = std::clamp(int(std::floor((out.y + 0.5) / reduction)), 0, colour.rows - 1);
    if (colour.channels() == 3) {
      const cv::Vec3b bgr = colour.at<cv::Vec3b>(py, px);
      out.b = bgr[0];
      out.g = bgr[1];
      out.r = bgr[2];
    } else {
      out.r = out.g = out.b = colour.at<std::uint8_t>(py, px);
    }
    // Whole numbers 0-255 as OpenCV computes them (SiftDescriptors): the
    // rounding and clamping change nothing.
    const float* sift = cv_descriptors.ptr<float>(kept[i]);
    for (int k = 0; k < 128; ++k) {
      features.descriptors(i, k) = std::uint8_t(std::clamp(std::lround(sift[k]), 0L, 255L));
    }
  }
  return features;
}

void WriteFeatureSet(std::ostream& out, const FeatureSet& features) {
  WriteValue(out, features.width);
  WriteValue(out, features.height);
  WriteVector(out, features.keypoints);
  out.write(reinterpret_cast<const char*>(features.descriptors.data()),
            std::streamsize(features.descriptors.size()));
}

FeatureSet ReadFeatureSet(std::istream& in) {
  FeatureSet features;
  features.width = ReadValue<int>(in, "feature image width");
  features.height = ReadValue<int>(in, "feature image height");
  features.keypoints = ReadVector<Keypoint>(in, "keypoints", std::size_t(1) << 24);
  features.descriptors.resize(features.size(), 128);
  if (!in.read(reinterpret_cast<char*>(features.descriptors.data()),
               std::streamsize(features.descriptors.size()))) {
    throw std::runtime_error("file truncated while reading descriptors");
  }
  return features;
}

}  // namespace flysfm
