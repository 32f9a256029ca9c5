#include "core/malloc_policy.h"

#include <cstdlib>  // defines __GLIBC__ where the C library is glibc

#if defined(__GLIBC__)
#include <malloc.h>
#endif

namespace flysfm {

bool MallocPolicy::Check() const {
  return max_arenas >= 1 && mmap_threshold_bytes > 0 && trim_threshold_bytes >= 0;
}

bool ApplyMallocPolicy(const MallocPolicy& policy) {
  if (!policy.Check()) return false;
#if defined(__GLIBC__)
  // mallopt returns 1 on success, 0 on a refused value. Under a sanitizer
  // its allocator, not glibc's, serves malloc, whatever mallopt returns.
  return mallopt(M_ARENA_MAX, policy.max_arenas) == 1 &&
         mallopt(M_MMAP_THRESHOLD, policy.mmap_threshold_bytes) == 1 &&
         mallopt(M_TRIM_THRESHOLD, policy.trim_threshold_bytes) == 1;
#else
  return false;
#endif
}

}  // namespace flysfm
