#pragma once

// Rendered captures for tests, each rendered once per build rather than once
// per test process: every Catch2 case runs as a process of its own, and the
// end-to-end engine tests render the same capture in each (12 views take
// about 2 s in Release and 30 s under AddressSanitizer). The cache is keyed
// by every option of the capture and by a hash of the renderer's sources
// (io/synthetic, taken when CMake configures, which an edit of them
// triggers), so a cached capture is always the one the renderer would make.

#include "io/synthetic/synthetic_source.h"

namespace flysfm::testing {

// MakeSyntheticCapture(options), from the cache folder of the build
// (FLYSFM_TEST_CACHE_DIR, or $FLYSFM_TEST_CACHE when set) when it holds it;
// else rendered and stored there for the next process. A cache that cannot
// be read or written is ignored: the capture is rendered.
SyntheticCapture RenderedCapture(const SyntheticCaptureOptions& options);

}  // namespace flysfm::testing
