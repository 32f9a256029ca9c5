#pragma once

// Matches of every image pair seen so far, raw (after the descriptor tests)
// and verified (after two-view geometry), keyed by the unordered pair.

#include <cstdint>
#include <unordered_map>
#include <utility>
#include <vector>

#include "matching/matcher.h"

namespace flysfm {

// A key for the unordered pair {image_id1, image_id2}; ids are non-negative
// and distinct.
std::uint64_t ImagePairKey(int image_id1, int image_id2);
std::pair<int, int> ImagePairFromKey(std::uint64_t key);

class MatchStore {
 public:
  // Matches are given and returned oriented from image_id1 to image_id2
  // (idx1 in image_id1), whichever order the pair was stored in. Setting
  // again replaces.
  void SetRawMatches(int image_id1, int image_id2, std::vector<FeatureMatch> matches);
  void SetVerifiedMatches(int image_id1, int image_id2, std::vector<FeatureMatch> matches);

  bool HasPair(int image_id1, int image_id2) const;
  // Whether verification has run for the pair (its result may be empty).
  bool HasVerified(int image_id1, int image_id2) const;
  // Empty when the pair is unknown.
  std::vector<FeatureMatch> RawMatches(int image_id1, int image_id2) const;
  std::vector<FeatureMatch> VerifiedMatches(int image_id1, int image_id2) const;

  // Every stored pair, smaller id first, in ascending order.
  std::vector<std::pair<int, int>> Pairs() const;
  // The images paired with `image_id` that have at least `min_verified`
  // verified matches, ascending.
  std::vector<int> VerifiedNeighbours(int image_id, int min_verified = 1) const;

  void RemoveImage(int image_id);
  std::size_t NumPairs() const { return pairs_.size(); }

 private:
  struct PairMatches {
    // Oriented from the smaller image id to the larger.
    std::vector<FeatureMatch> raw;
    std::vector<FeatureMatch> verified;
    bool has_verified = false;
  };
  PairMatches& Entry(int image_id1, int image_id2);
  const PairMatches* Find(int image_id1, int image_id2) const;

  std::unordered_map<std::uint64_t, PairMatches> pairs_;
};

}  // namespace flysfm
