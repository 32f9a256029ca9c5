#pragma once

// Descriptor matching between two images: nearest neighbours, Lowe's ratio
// test and the mutual nearest-neighbour check. Two back-ends behind one call:
// exact (brute force) and approximate (FLANN randomised kd-trees).

#include <vector>

#include "matching/features.h"

namespace flysfm {

struct FeatureMatch {
  int idx1 = -1;  // row in the first image's descriptors
  int idx2 = -1;  // row in the second image's descriptors

  bool operator==(const FeatureMatch& other) const {
    return idx1 == other.idx1 && idx2 == other.idx2;
  }
};

enum class MatcherBackend {
  // All distances, as one matrix product (both directions from one product).
  kExact,
  // FLANN randomised kd-trees: faster for large sets, may miss a neighbour.
  kApproximate,
};

struct MatchOptions {
  MatcherBackend backend = MatcherBackend::kExact;
  // Lowe's ratio of nearest to second-nearest distance; a match passes when
  // below it. 0.8 is Lowe's value (COLMAP's too).
  double max_ratio = 0.8;
  // Keep i <-> j only when i is also j's nearest neighbour in image 1.
  bool mutual = true;
  // Matches with a larger descriptor distance are dropped. RootSIFT
  // descriptors have unit norm, so distances lie in [0, 2]; 2 disables it.
  double max_distance = 2.0;
  // Approximate back-end: number of randomised kd-trees and of leaves checked
  // per query (FLANN's accuracy knob; 64 finds the true neighbour in most
  // queries at a fraction of the exact cost).
  int flann_num_trees = 4;
  int flann_num_checks = 64;

  bool Check() const;
};

// Matches of image 1's descriptors to image 2's, ordered by idx1. Bad options
// are bad input: std::invalid_argument. Empty inputs give no matches.
std::vector<FeatureMatch> MatchDescriptors(const FeatureDescriptors& descriptors1,
                                           const FeatureDescriptors& descriptors2,
                                           const MatchOptions& options);

}  // namespace flysfm
