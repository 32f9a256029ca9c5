#pragma once

// Whether this build runs under AddressSanitizer or ThreadSanitizer (GCC
// defines these; UndefinedBehaviorSanitizer runs with AddressSanitizer in
// this project), where the engine runs 5-30 times slower than in Release.
// End-to-end tests then render smaller captures; docs/testing.md lists
// which, and each keeps every assertion it makes in Release.

namespace flysfm::testing {

#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
constexpr bool kSanitizerBuild = true;
#else
constexpr bool kSanitizerBuild = false;
#endif

}  // namespace flysfm::testing
