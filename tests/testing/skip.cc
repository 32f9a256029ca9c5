#include "tests/testing/skip.h"

#include <cstdlib>
#include <cstring>
#include <iostream>

namespace flysfm::testing {

void SkipTest(const std::string& why) {
  const char* require = std::getenv("FLYSFM_REQUIRE_DATA");
  if (require && std::strcmp(require, "1") == 0) {
    std::cout << "failed: " << why << " (FLYSFM_REQUIRE_DATA=1)" << std::endl;
    std::exit(EXIT_FAILURE);
  }
  std::cout << "skipped: " << why << std::endl;
  std::exit(77);
}

void SkipInThisBuild(const std::string& why) {
  std::cout << "skipped: " << why << std::endl;
  std::exit(77);
}

}  // namespace flysfm::testing
