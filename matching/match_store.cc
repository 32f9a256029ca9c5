#include "matching/match_store.h"

#include <algorithm>
#include <stdexcept>
#include <string>

namespace flysfm {
namespace {

void Swap(std::vector<FeatureMatch>* matches) {
  for (FeatureMatch& m : *matches) std::swap(m.idx1, m.idx2);
}

std::vector<FeatureMatch> Oriented(std::vector<FeatureMatch> matches, bool swap) {
  if (swap) Swap(&matches);
  return matches;
}

}  // namespace

std::uint64_t ImagePairKey(int image_id1, int image_id2) {
  if (image_id1 < 0 || image_id2 < 0 || image_id1 == image_id2) {
    throw std::invalid_argument("invalid image pair (" + std::to_string(image_id1) +
                                ", " + std::to_string(image_id2) + ")");
  }
  const auto low = std::uint64_t(std::min(image_id1, image_id2));
  const auto high = std::uint64_t(std::max(image_id1, image_id2));
  return (low << 32) | high;
}

std::pair<int, int> ImagePairFromKey(std::uint64_t key) {
  return {int(key >> 32), int(key & 0xFFFFFFFFu)};
}

MatchStore::PairMatches& MatchStore::Entry(int image_id1, int image_id2) {
  return pairs_[ImagePairKey(image_id1, image_id2)];
}

const MatchStore::PairMatches* MatchStore::Find(int image_id1, int image_id2) const {
  const auto it = pairs_.find(ImagePairKey(image_id1, image_id2));
  return it == pairs_.end() ? nullptr : &it->second;
}

void MatchStore::SetRawMatches(int image_id1, int image_id2,
                               std::vector<FeatureMatch> matches) {
  Entry(image_id1, image_id2).raw = Oriented(std::move(matches), image_id1 > image_id2);
}

void MatchStore::SetVerifiedMatches(int image_id1, int image_id2,
                                    std::vector<FeatureMatch> matches) {
  PairMatches& entry = Entry(image_id1, image_id2);
  entry.verified = Oriented(std::move(matches), image_id1 > image_id2);
  entry.has_verified = true;
}

bool MatchStore::HasPair(int image_id1, int image_id2) const {
  return Find(image_id1, image_id2) != nullptr;
}

bool MatchStore::HasVerified(int image_id1, int image_id2) const {
  const PairMatches* entry = Find(image_id1, image_id2);
  return entry != nullptr && entry->has_verified;
}

std::vector<FeatureMatch> MatchStore::RawMatches(int image_id1, int image_id2) const {
  const PairMatches* entry = Find(image_id1, image_id2);
  if (entry == nullptr) return {};
  return Oriented(entry->raw, image_id1 > image_id2);
}

std::vector<FeatureMatch> MatchStore::VerifiedMatches(int image_id1, int image_id2) const {
  const PairMatches* entry = Find(image_id1, image_id2);
  if (entry == nullptr) return {};
  return Oriented(entry->verified, image_id1 > image_id2);
}

std::vector<std::pair<int, int>> MatchStore::Pairs() const {
  std::vector<std::pair<int, int>> result;
  result.reserve(pairs_.size());
  for (const auto& [key, entry] : pairs_) result.push_back(ImagePairFromKey(key));
  std::sort(result.begin(), result.end());
  return result;
}

std::vector<int> MatchStore::VerifiedNeighbours(int image_id, int min_verified) const {
  std::vector<int> result;
  for (const auto& [key, entry] : pairs_) {
    if (!entry.has_verified || int(entry.verified.size()) < min_verified) continue;
    const auto [a, b] = ImagePairFromKey(key);
    if (a == image_id) result.push_back(b);
    if (b == image_id) result.push_back(a);
  }
  std::sort(result.begin(), result.end());
  return result;
}

void MatchStore::RemoveImage(int image_id) {
  for (auto it = pairs_.begin(); it != pairs_.end();) {
    const auto [a, b] = ImagePairFromKey(it->first);
    it = (a == image_id || b == image_id) ? pairs_.erase(it) : std::next(it);
  }
}

}  // namespace flysfm
