#include "matching/match_store.h"

#include <stdexcept>

#include <catch2/catch.hpp>

namespace flysfm {
namespace {

TEST_CASE("match store orients matches by the requested pair order") {
  MatchStore store;
  store.SetRawMatches(7, 3, {{1, 10}, {2, 20}});
  CHECK(store.HasPair(3, 7));
  CHECK_FALSE(store.HasVerified(7, 3));
  CHECK(store.RawMatches(7, 3) == std::vector<FeatureMatch>{{1, 10}, {2, 20}});
  CHECK(store.RawMatches(3, 7) == std::vector<FeatureMatch>{{10, 1}, {20, 2}});

  store.SetVerifiedMatches(3, 7, {{20, 2}});
  CHECK(store.HasVerified(7, 3));
  CHECK(store.VerifiedMatches(7, 3) == std::vector<FeatureMatch>{{2, 20}});
  // Raw matches stay.
  CHECK(store.RawMatches(3, 7).size() == 2);
}

TEST_CASE("match store lists pairs and verified neighbours and removes images") {
  MatchStore store;
  store.SetRawMatches(1, 2, {{0, 0}});
  store.SetVerifiedMatches(1, 2, {{0, 0}});
  store.SetVerifiedMatches(3, 1, {});
  store.SetRawMatches(2, 3, {{4, 5}});
  CHECK(store.Pairs() == std::vector<std::pair<int, int>>{{1, 2}, {1, 3}, {2, 3}});
  CHECK(store.VerifiedNeighbours(1) == std::vector<int>{2});
  CHECK(store.VerifiedNeighbours(1, 0) == std::vector<int>{2, 3});
  CHECK(store.RawMatches(5, 6).empty());
  store.RemoveImage(2);
  CHECK(store.Pairs() == std::vector<std::pair<int, int>>{{1, 3}});
  CHECK(store.NumPairs() == 1);
}

TEST_CASE("pair keys round-trip and reject invalid pairs") {
  CHECK(ImagePairFromKey(ImagePairKey(9, 4)) == std::pair<int, int>{4, 9});
  CHECK(ImagePairKey(4, 9) == ImagePairKey(9, 4));
  CHECK_THROWS_AS(ImagePairKey(2, 2), std::invalid_argument);
  CHECK_THROWS_AS(ImagePairKey(-1, 2), std::invalid_argument);
}

}  // namespace
}  // namespace flysfm
