#include "matching/match_store.h"

#include <algorithm>
#include <stdexcept>
#include <string>

namespace flysfm {
namespace {

std::vector<FeatureMatch> Oriented(std::vector<FeatureMatch> matches, bool swap) {
  if (swap) {
    for (FeatureMatch& m : matches) std::swap(m.idx1, m.idx2);
  }
  return matches;
}

void InsertSorted(image_t id, std::vector<image_t>* ids) {
  const auto it = std::lower_bound(ids->begin(), ids->end(), id);
  if (it == ids->end() || *it != id) ids->insert(it, id);
}

void EraseSorted(image_t id, std::vector<image_t>* ids) {
  const auto it = std::lower_bound(ids->begin(), ids->end(), id);
  if (it != ids->end() && *it == id) ids->erase(it);
}

}  // namespace

std::uint64_t ImagePairKey(image_t image_id1, image_t image_id2) {
  if (image_id1 == kInvalidImageId || image_id2 == kInvalidImageId ||
      image_id1 == image_id2) {
    throw std::invalid_argument("invalid image pair (" + std::to_string(image_id1) +
                                ", " + std::to_string(image_id2) + ")");
  }
  const auto low = std::uint64_t(std::min(image_id1, image_id2));
  const auto high = std::uint64_t(std::max(image_id1, image_id2));
  return (low << 32) | high;
}

std::pair<image_t, image_t> ImagePairFromKey(std::uint64_t key) {
  return {image_t(key >> 32), image_t(key & 0xFFFFFFFFu)};
}

void MatchStore::SetMatches(image_t image_id1, image_t image_id2,
                            std::vector<FeatureMatch> matches) {
  const std::uint64_t key = ImagePairKey(image_id1, image_id2);
  if (matches.empty()) {
    if (pairs_.erase(key) > 0) {
      EraseSorted(image_id2, &neighbours_[image_id1]);
      EraseSorted(image_id1, &neighbours_[image_id2]);
    }
    return;
  }
  pairs_[key] = Oriented(std::move(matches), image_id1 > image_id2);
  InsertSorted(image_id2, &neighbours_[image_id1]);
  InsertSorted(image_id1, &neighbours_[image_id2]);
}

std::vector<FeatureMatch> MatchStore::Matches(image_t image_id1, image_t image_id2) const {
  const auto it = pairs_.find(ImagePairKey(image_id1, image_id2));
  if (it == pairs_.end()) return {};
  return Oriented(it->second, image_id1 > image_id2);
}

std::size_t MatchStore::NumMatches(image_t image_id1, image_t image_id2) const {
  const auto it = pairs_.find(ImagePairKey(image_id1, image_id2));
  return it == pairs_.end() ? 0 : it->second.size();
}

const std::vector<image_t>& MatchStore::Neighbours(image_t image_id) const {
  static const std::vector<image_t> kNone;
  const auto it = neighbours_.find(image_id);
  return it == neighbours_.end() ? kNone : it->second;
}

std::vector<std::pair<image_t, image_t>> MatchStore::Pairs() const {
  std::vector<std::pair<image_t, image_t>> result;
  result.reserve(pairs_.size());
  for (const auto& [key, matches] : pairs_) result.push_back(ImagePairFromKey(key));
  std::sort(result.begin(), result.end());
  return result;
}

void MatchStore::RemoveImage(image_t image_id) {
  const auto it = neighbours_.find(image_id);
  if (it == neighbours_.end()) return;
  for (const image_t other : it->second) {
    pairs_.erase(ImagePairKey(image_id, other));
    EraseSorted(image_id, &neighbours_[other]);
  }
  neighbours_.erase(it);
}

}  // namespace flysfm
