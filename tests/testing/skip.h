#pragma once

#include <string>

namespace flysfm::testing {

// Ends a test that cannot run here because something from outside the
// repository is missing (the shared data folder, the colmap program): prints
// "skipped: <why>" and exits with 77, which CTest reports as skipped (each
// Catch2 case runs as its own process; Catch2 v2 has no skip of its own).
// Where FLYSFM_REQUIRE_DATA=1 (CI, where everything must be present), it
// prints "failed: <why>" and exits with 1 instead.
[[noreturn]] void SkipTest(const std::string& why);

// Ends a test that cannot run in this build at all (under a sanitizer whose
// allocator replaces glibc's, say): "skipped: <why>", exit 77, whatever
// FLYSFM_REQUIRE_DATA says, since nothing CI could provide is missing.
[[noreturn]] void SkipInThisBuild(const std::string& why);

}  // namespace flysfm::testing
