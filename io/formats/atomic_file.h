#pragma once

#include <filesystem>
#include <functional>
#include <ostream>

namespace flysfm {

// Writes `path` through a temporary file beside it, renamed over `path` once
// complete and flushed: a reader (or a crash) never sees half a file. Throws
// std::runtime_error naming the path when the file cannot be written.
void WriteFileAtomically(const std::filesystem::path& path,
                         const std::function<void(std::ostream&)>& write,
                         bool binary = false);

}  // namespace flysfm
