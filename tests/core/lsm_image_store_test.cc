#include "core/lsm_image_store.h"

#include <catch2/catch.hpp>
#include <opencv2/core.hpp>

namespace flysfm {
namespace {

cv::Mat Noise(int seed) {
  cv::Mat grey(200, 300, CV_8U);
  cv::theRNG().state = seed;
  cv::randu(grey, 0, 255);
  return grey;
}

TEST_CASE("The store builds each pyramid once and keeps the cache within its budget") {
  LsmImageStore::Options options;
  options.num_pyramid_levels = 2;
  options.cache_megabytes = 0;  // keeps only the most recent pyramid
  LsmImageStore store(options);
  store.Add(1, Noise(1));
  store.Add(2, Noise(2));
  const std::vector<LsmImage> first = store.Pyramid(1);
  REQUIRE(first.size() == 2);
  const std::size_t one = store.cache_bytes();
  CHECK(one > 0);
  // The second evicts the first; the first's levels stay valid for their
  // holder, and a rebuilt pyramid is the same.
  store.Pyramid(2);
  CHECK(store.cache_bytes() == one);
  const std::vector<LsmImage> rebuilt = store.Pyramid(1);
  CHECK(cv::norm(rebuilt.front().pixels(), first.front().pixels(), cv::NORM_INF) == 0);

  options.cache_megabytes = 64;
  LsmImageStore roomy(options);
  roomy.Add(1, Noise(1));
  roomy.Add(2, Noise(2));
  roomy.Pyramid(1);
  roomy.Pyramid(2);
  CHECK(roomy.cache_bytes() == 2 * one);
  options.num_pyramid_levels = 0;
  CHECK_THROWS_AS(LsmImageStore(options), std::invalid_argument);
}

}  // namespace
}  // namespace flysfm
