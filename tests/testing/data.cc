#include "tests/testing/data.h"

#include <cstdlib>

namespace flysfm::testing {

std::string DataDir() {
  if (const char* env = std::getenv("FLYSFM_DATA"); env && *env) return env;
  return FLYSFM_DEFAULT_DATA_DIR;
}

std::string DataPath(const std::string& relative) {
  return DataDir() + "/" + relative;
}

}  // namespace flysfm::testing
