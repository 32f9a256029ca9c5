// Regression tests read real data from the shared data folder. Where it is
// absent (a user's fresh machine) they skip with a message instead of
// failing; CTest maps exit code 77 to "skipped". With FLYSFM_REQUIRE_DATA=1
// (CI) an absent folder fails them instead (testing::SkipTest).
#define CATCH_CONFIG_RUNNER
#include <catch2/catch.hpp>

#include <filesystem>

#include "tests/testing/data.h"
#include "tests/testing/skip.h"

int main(int argc, char* argv[]) {
  Catch::Session session;
  if (const int rc = session.applyCommandLine(argc, argv); rc != 0) return rc;
  const auto& config = session.configData();
  const bool listing = config.listTests || config.listTestNamesOnly ||
                       config.listTags || config.listReporters;
  if (!listing && !std::filesystem::is_directory(flysfm::testing::DataDir())) {
    flysfm::testing::SkipTest("shared data folder not found at " +
                              flysfm::testing::DataDir() +
                              " (set FLYSFM_DATA to its location)");
  }
  return session.run();
}
