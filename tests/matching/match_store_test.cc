#include "matching/match_store.h"

#include <stdexcept>

#include <catch2/catch.hpp>

namespace flysfm {
namespace {

TEST_CASE("match store orients matches by the requested pair order") {
  MatchStore store;
  store.SetMatches(7, 3, {{1, 10}, {2, 20}});
  CHECK(store.Matches(7, 3) == std::vector<FeatureMatch>{{1, 10}, {2, 20}});
  CHECK(store.Matches(3, 7) == std::vector<FeatureMatch>{{10, 1}, {20, 2}});
  CHECK(store.NumMatches(3, 7) == 2);
  store.SetMatches(3, 7, {{20, 2}});
  CHECK(store.Matches(7, 3) == std::vector<FeatureMatch>{{2, 20}});
}

TEST_CASE("match store keeps each image's neighbours and removes images") {
  MatchStore store;
  store.SetMatches(1, 2, {{0, 0}});
  store.SetMatches(3, 1, {});  // no matches: not a pair
  store.SetMatches(2, 3, {{4, 5}});
  store.SetMatches(4, 2, {{1, 1}});
  CHECK(store.Pairs() == std::vector<std::pair<image_t, image_t>>{{1, 2}, {2, 3}, {2, 4}});
  CHECK(store.Neighbours(1) == std::vector<image_t>{2});
  CHECK(store.Neighbours(2) == std::vector<image_t>{1, 3, 4});
  CHECK(store.Neighbours(9).empty());
  CHECK(store.Matches(5, 6).empty());
  store.RemoveImage(2);
  CHECK(store.NumPairs() == 0);
  CHECK(store.Neighbours(1).empty());
  CHECK(store.Neighbours(3).empty());
  // Clearing a pair's matches removes it from both adjacencies.
  store.SetMatches(5, 6, {{0, 1}});
  store.SetMatches(6, 5, {});
  CHECK(store.Neighbours(5).empty());
  CHECK(store.NumPairs() == 0);
}

TEST_CASE("pair keys round-trip and reject invalid pairs") {
  CHECK(ImagePairFromKey(ImagePairKey(9, 4)) == std::pair<image_t, image_t>{4, 9});
  CHECK(ImagePairKey(4, 9) == ImagePairKey(9, 4));
  CHECK_THROWS_AS(ImagePairKey(2, 2), std::invalid_argument);
  CHECK_THROWS_AS(ImagePairKey(kInvalidImageId, 2), std::invalid_argument);
}

}  // namespace
}  // namespace flysfm
