#pragma once

// Local features: SIFT keypoints (OpenCV) with their pixel colour and
// RootSIFT descriptors.

#include <cstdint>
#include <istream>
#include <ostream>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core.hpp>

namespace flysfm {

struct Keypoint {
  // Full-resolution pixel coordinates, OpenCV convention (the centre of the
  // top-left pixel is (0, 0)).
  float x = 0.f;
  float y = 0.f;
  // SIFT scale as OpenCV reports it (keypoint diameter), in full-resolution
  // pixels.
  float scale = 0.f;
  // Radians: OpenCV's KeyPoint::angle (degrees, in the image coordinate
  // system) converted, same sense.
  float orientation = 0.f;
  // Colour of the pixel under the keypoint, for coloured point clouds.
  std::uint8_t r = 0;
  std::uint8_t g = 0;
  std::uint8_t b = 0;
};

// One RootSIFT descriptor per row (unit L2 norm): what matching and
// retrieval compare. Row-major, so that a row is contiguous and the block can
// be handed to OpenCV and BLAS without a copy. 1 500 features take 768 kB.
using FeatureDescriptors = Eigen::Matrix<float, Eigen::Dynamic, 128, Eigen::RowMajor>;

// SIFT descriptors as OpenCV computes them, one per row. OpenCV rounds each
// bin to a byte before it hands floats back (whole numbers 0-255), so a byte
// holds each exactly: the engine keeps every image's descriptors, and its
// checkpoint writes them, in a quarter of floats' memory, and RootSift()
// gives, bit for bit, what floats would have given. 1 500 features take
// 192 kB.
using SiftDescriptors = Eigen::Matrix<std::uint8_t, Eigen::Dynamic, 128, Eigen::RowMajor>;

struct FeatureSet {
  // Size of the full-resolution image the keypoints refer to.
  int width = 0;
  int height = 0;
  std::vector<Keypoint> keypoints;
  // Row i describes keypoints[i]; RootSift(descriptors) is what is compared.
  SiftDescriptors descriptors;

  int size() const { return static_cast<int>(keypoints.size()); }
};

struct SiftOptions {
  // Features kept. Matching grows with the square of the count and every
  // later stage with the count: 1 500 kept fr1_xyz's ATE of 2 000 (1.09 cm
  // on 120 frames) at a little over half the matching time, and bounds
  // matching and memory on photos.
  int max_num_features = 1500;
  // Share of the kept features chosen by the largest scale, the rest by the
  // strongest DoG response (OpenCV's own choice). On photos the strongest
  // responses are mostly fine texture that another viewpoint does not
  // repeat; the coarse blobs are what a photo from nearer, from the side or
  // against the sun still shares (sceaux_castle: 9 of 11 photos registered
  // with none, all 11 with half), the fine ones are the precise ones
  // (fountain-P11, all by scale: 2.6 mm instead of 2.1). docs/engine.md,
  // step 2.
  double large_scale_share = 0.5;
  // Longest image side used for extraction; larger images are downscaled
  // (area interpolation) and keypoints mapped back to full resolution. 1 600
  // px keeps a 6 MP photo near 0.3 s instead of over 1 s, with enough
  // features for pose estimation.
  int max_image_size = 1600;
  // OpenCV SIFT's contrast threshold on the DoG peaks (its default; Lowe's
  // 0.03 in OpenCV's scaling).
  double peak_threshold = 0.04;
  // Ratio of principal curvatures above which edge responses are rejected
  // (Lowe's 10).
  double edge_threshold = 10.0;
  // Scale levels per octave (Lowe's 3).
  int num_octave_layers = 3;

  bool Check() const;
};

// Extracts SIFT features from an 8-bit grey or BGR image. An empty or
// non-8-bit image is bad input: std::invalid_argument. An image without
// texture gives an empty set.
FeatureSet ExtractFeatures(const cv::Mat& image, const SiftOptions& options);
// The same when the caller has the image in grey already (the engine keeps it
// for LSM): `grey` is the image in 8-bit grey at full size; `colour`, which
// gives the keypoints' colours, is it in grey or BGR at full size or reduced
// by 2, 4 or 8 as JPEG's DCT scaling gives it (each side rounded up).
FeatureSet ExtractFeatures(const cv::Mat& colour, cv::Mat grey, const SiftOptions& options);

// A feature set in the engine's checkpoint format. Read throws
// std::runtime_error on a truncated or inconsistent stream.
void WriteFeatureSet(std::ostream& out, const FeatureSet& features);
FeatureSet ReadFeatureSet(std::istream& in);

// In place: L1-normalise each row, then take the element-wise square root
// (Arandjelovic & Zisserman 2012), so the Euclidean distance of RootSIFT
// descriptors is the Hellinger distance of the SIFT histograms.
void RootSiftInPlace(FeatureDescriptors* descriptors);
// The RootSIFT descriptors of `sift` (about 0.1 ms for 1 500 features).
FeatureDescriptors RootSift(const SiftDescriptors& sift);

}  // namespace flysfm
