#pragma once

namespace flysfm {

// How the process's allocator (glibc's malloc) keeps the memory of one
// image's transient buffers for the next image's, instead of handing it back
// to the system and faulting it in again. Each image's decode and SIFT run on
// a thread of their own (the next image's, beside the engine's work on this
// one) and allocate a few hundred MB in blocks of up to tens of MB (SIFT's
// Gaussian and DoG layers of a 1 600-pixel copy doubled, 27 MB each), freed
// when the features are out. glibc's defaults give that thread an arena of
// its own, whose 64 MB heaps are unmapped as soon as they are free, and slide
// the size above which a block is mapped by itself: on bench_photos' 6 MP
// photos that is 4.1 million page faults, a quarter of the run's CPU time in the
// kernel and SIFT's median doubled (docs/engine.md, "The allocator").
struct MallocPolicy {
  // One arena for every thread: what a thread frees, another reuses.
  int max_arenas = 1;
  // Blocks of this size or larger are mapped and unmapped by themselves
  // (glibc's largest setting; fixed, it no longer slides). A 24 MP photo's
  // whole-image buffers are; SIFT's layers of its 1 600-pixel copy are not.
  int mmap_threshold_bytes = 32 << 20;
  // Free memory at the heap's top kept for the next image rather than
  // returned: SIFT's working set at 1 600 pixels (about 400 MB) with margin.
  // It lies under the peak the same image reached; the peak grew by 2-4 %
  // only (one arena's holes fit less tightly).
  int trim_threshold_bytes = 512 << 20;

  bool Check() const;
};

// Sets the policy. Call it first in main, before any thread starts: arenas
// made before it stay. False when an option fails Check(), the C library is
// not glibc or it refused a setting: the program then runs as before, only
// slower. Under ASan or TSan their allocator serves malloc whatever this sets.
bool ApplyMallocPolicy(const MallocPolicy& policy = MallocPolicy());

}  // namespace flysfm
