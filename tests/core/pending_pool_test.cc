#include "core/pending_pool.h"

#include <map>

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

}  // namespace
}  // namespace flysfm
