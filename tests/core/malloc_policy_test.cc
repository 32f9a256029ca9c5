#include "core/malloc_policy.h"

#include <sys/resource.h>

#include <cstdlib>
#include <cstring>
#include <future>
#include <iostream>
#include <string>
#include <vector>

#include <catch2/catch.hpp>

#include "tests/testing/skip.h"

namespace flysfm {
namespace {

#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
constexpr bool kSanitizerAllocator = true;
#elif defined(__has_feature)
#if __has_feature(address_sanitizer) || __has_feature(thread_sanitizer)
constexpr bool kSanitizerAllocator = true;
#else
constexpr bool kSanitizerAllocator = false;
#endif
#else
constexpr bool kSanitizerAllocator = false;
#endif

// What one image's SIFT does on a thread of its own: blocks of 27 MB (a
// layer of a 1 600-pixel copy, doubled) written and freed. Returns that
// thread's page faults.
long FaultsOfOneImagesThread() {
  return std::async(std::launch::async, [] {
           rusage before;
           getrusage(RUSAGE_THREAD, &before);
           std::vector<char*> layers;
           for (int i = 0; i < 6; ++i) {
             const std::size_t bytes = std::size_t(27) << 20;
             layers.push_back(static_cast<char*>(std::malloc(bytes)));
             std::memset(layers.back(), 1, bytes);
           }
           for (char* layer : layers) std::free(layer);
           rusage after;
           getrusage(RUSAGE_THREAD, &after);
           return after.ru_minflt - before.ru_minflt;
         })
      .get();
}

TEST_CASE("ApplyMallocPolicy: the next image's thread reuses the pages of the last one's") {
  if (kSanitizerAllocator) {
    testing::SkipInThisBuild(
        "built with AddressSanitizer or ThreadSanitizer, whose allocator serves malloc "
        "whatever mallopt sets: there is no glibc arena whose pages to count");
  }
  REQUIRE(ApplyMallocPolicy());
  const long first = FaultsOfOneImagesThread();
  const long second = FaultsOfOneImagesThread();
  // The first thread faults its 162 MB in once (41 472 pages of 4 kB, fewer
  // where transparent huge pages back them); the second finds them there.
  CHECK(first > 0);
  CHECK(second <= first / 10);
}

TEST_CASE("MallocPolicy::Check rejects what the allocator cannot take") {
  CHECK(MallocPolicy().Check());
  MallocPolicy policy;
  policy.max_arenas = 0;
  CHECK_FALSE(policy.Check());
  CHECK_FALSE(ApplyMallocPolicy(policy));
  policy = MallocPolicy();
  policy.mmap_threshold_bytes = 0;
  CHECK_FALSE(policy.Check());
  policy = MallocPolicy();
  policy.trim_threshold_bytes = -1;
  CHECK_FALSE(policy.Check());
}

}  // namespace
}  // namespace flysfm
