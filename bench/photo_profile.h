#pragma once

// bench_photos --profile (photo_profile.cc).

#include <vector>

#include <nlohmann/json.hpp>

#include "core/engine.h"

namespace flysfm::bench {

// Sample pairs of `frames` (a session in path order) matched and verified
// again offline, each RANSAC timed, at photo, feature and video pixel
// scales; decoding and SIFT alone; one LSM pyramid at full resolution and
// at 640x480. Prints a table and returns its figures.
nlohmann::json ProfilePhotoPairs(const std::vector<Frame>& frames, const Camera& camera,
                                 const Engine::Options& options);

}  // namespace flysfm::bench
