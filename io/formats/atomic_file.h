#pragma once

#include <filesystem>
#include <functional>
#include <ostream>

namespace flysfm {

// Writes `path` through a temporary file beside it, renamed over `path` once
// complete and flushed: a reader (or a crash) never sees half a file. Throws
// std::runtime_error naming the path and the reason (errno's message, or the
// exception `write` threw) when the file cannot be written; the temporary is
// removed then and `path` is as it was.
void WriteFileAtomically(const std::filesystem::path& path,
                         const std::function<void(std::ostream&)>& write,
                         bool binary = false);

}  // namespace flysfm
