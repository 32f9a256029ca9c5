#include "core/pending_pool.h"

#include <map>
#include <sstream>

#include <catch2/catch.hpp>

namespace flysfm {
namespace {

TEST_CASE("A waiting image is due when its registered neighbourhood changed since its try") {
  PendingPool pool;
  std::map<image_t, int> neighbours = {{1, 0}, {2, 3}, {3, 1}};
  const auto count = [&](image_t id) { return neighbours.at(id); };
  pool.Add(1);
  pool.Add(2);
  pool.Add(3);
  // Never tried: due in arrival order, but not without a registered neighbour.
  CHECK(pool.NextDue(count) == 2);
  pool.MarkTried(2, 3);
  CHECK(pool.NextDue(count) == 3);
  pool.MarkTried(3, 1);
  CHECK(pool.NextDue(count) == kInvalidImageId);
  neighbours[2] = 4;
  CHECK(pool.NextDue(count) == 2);
  pool.Remove(2);
  CHECK(pool.Images() == std::vector<image_t>{1, 3});
  CHECK(pool.NextDue(count) == kInvalidImageId);
  // The end of a batch: every image is due once more.
  pool.ForgetTries();
  CHECK(pool.NextDue(count) == 3);
  CHECK_FALSE(pool.empty());
}

TEST_CASE("A pool restored from its checkpoint keeps its order and its tries") {
  PendingPool pool;
  pool.Add(4);
  pool.Add(2);
  pool.MarkTried(2, 5);
  std::stringstream stream;
  pool.Write(stream);
  PendingPool restored;
  restored.Read(stream);
  CHECK(restored.Images() == std::vector<image_t>{4, 2});
  // Image 2 saw 5 neighbours at its try: not due with 5, due with 6.
  CHECK(restored.NextDue([](image_t id) { return id == 2 ? 5 : 0; }) == kInvalidImageId);
  CHECK(restored.NextDue([](image_t id) { return id == 2 ? 6 : 0; }) == 2);
}

}  // namespace
}  // namespace flysfm
