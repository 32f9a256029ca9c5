#pragma once

// The verified matches of every image pair seen so far (after two-view
// geometry and LSM), with each image's adjacency, so that asking for an
// image's neighbours costs its own degree, not the session's pair count.

#include <cstdint>
#include <unordered_map>
#include <utility>
#include <vector>

#include "geometry/types.h"
#include "matching/matcher.h"

namespace flysfm {

// A key for the unordered pair {image_id1, image_id2}; the ids are distinct
// and valid.
std::uint64_t ImagePairKey(image_t image_id1, image_t image_id2);
std::pair<image_t, image_t> ImagePairFromKey(std::uint64_t key);

class MatchStore {
 public:
  // Matches are given and returned oriented from image_id1 to image_id2
  // (idx1 in image_id1), whichever order the pair was stored in. Setting
  // again replaces; a pair without matches is not stored.
  void SetMatches(image_t image_id1, image_t image_id2, std::vector<FeatureMatch> matches);
  // Empty when the pair is unknown.
  std::vector<FeatureMatch> Matches(image_t image_id1, image_t image_id2) const;
  std::size_t NumMatches(image_t image_id1, image_t image_id2) const;

  // The images sharing matches with `image_id`, ascending.
  const std::vector<image_t>& Neighbours(image_t image_id) const;

  // Every stored pair, smaller id first, in ascending order.
  std::vector<std::pair<image_t, image_t>> Pairs() const;
  void RemoveImage(image_t image_id);
  std::size_t NumPairs() const { return pairs_.size(); }

 private:
  // Oriented from the smaller image id to the larger.
  std::unordered_map<std::uint64_t, std::vector<FeatureMatch>> pairs_;
  std::unordered_map<image_t, std::vector<image_t>> neighbours_;
};

}  // namespace flysfm
