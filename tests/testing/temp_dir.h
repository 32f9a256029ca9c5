#pragma once

#include <filesystem>
#include <string>

namespace flysfm::testing {

// A new empty folder in the system's temporary folder, "flysfm_<name>_"
// plus a suffix unique to this call (mkdtemp): tests running at the same
// time (`ctest -j` runs every Catch case as its own process) never share one.
// It is removed, with what it holds, when the process exits.
std::filesystem::path MakeTempDir(const std::string& name);

}  // namespace flysfm::testing
