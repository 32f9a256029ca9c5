#pragma once

#include <string>

namespace flysfm::testing {

// The shared real-data folder: $FLYSFM_DATA if set, else the configured
// default (../shared/data beside the checkout).
std::string DataDir();

// DataDir() + "/" + relative.
std::string DataPath(const std::string& relative);

}  // namespace flysfm::testing
