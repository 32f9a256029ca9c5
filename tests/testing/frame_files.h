#pragma once

#include <filesystem>
#include <vector>

#include "core/scene/frame.h"

namespace flysfm::testing {

// `frames` (encoded bytes, as a synthetic capture gives them) written as
// files in `dir` (created), returned as frames that name their file
// instead: what a batch folder gives, and what a restarted engine decodes
// again.
std::vector<Frame> WriteFrameFiles(const std::vector<Frame>& frames,
                                   const std::filesystem::path& dir);

}  // namespace flysfm::testing
