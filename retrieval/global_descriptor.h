#pragma once

// A global image descriptor: one vector per image whose Euclidean distance
// ranks images by how likely they are to overlap. VLAD over RootSIFT is the
// default (vlad.h); a learnt CNN descriptor can be plugged in behind the same
// interface.

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "matching/features.h"

namespace flysfm {

class GlobalDescriptorExtractor {
 public:
  virtual ~GlobalDescriptorExtractor() = default;

  // Length of the descriptors Compute returns.
  virtual int Dim() const = 0;

  // The descriptor of one image, L2-normalised. Extractors built on local
  // features read `features`; those that read pixels (a CNN) read `image`,
  // the decoded 8-bit BGR frame, which the engine decodes reduced to about
  // SIFT's size (DecodedImage). An extractor may accept an empty `image`
  // when it does not use it (VLAD does).
  virtual Eigen::VectorXf Compute(const cv::Mat& image, const FeatureSet& features) const = 0;
};

}  // namespace flysfm
