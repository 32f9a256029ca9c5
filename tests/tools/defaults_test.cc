// docs/defaults.md and every default quoted in README.md and docs/*.md
// against the defaults the code defines (tools/defaults.h).

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include <catch2/catch.hpp>

#include "core/engine.h"
#include "tools/defaults.h"

namespace flysfm {
namespace {

namespace fs = std::filesystem;

const fs::path kSourceDir = FLYSFM_SOURCE_DIR;

std::string ReadText(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  REQUIRE(in);
  std::ostringstream text;
  text << in.rdbuf();
  return text.str();
}

const OptionDefault* Find(const std::vector<OptionDefault>& defaults, const std::string& key) {
  const auto it = std::find_if(defaults.begin(), defaults.end(),
                               [&](const OptionDefault& entry) { return entry.key == key; });
  return it == defaults.end() ? nullptr : &*it;
}

TEST_CASE("docs/defaults.md is what `flysfm defaults` prints") {
  const std::string expected = RenderOptionDefaults(ListOptionDefaults());
  const std::string actual = ReadText(kSourceDir / "docs" / "defaults.md");
  if (actual != expected) {
    // The first line that differs, not two whole pages.
    std::istringstream expected_lines(expected), actual_lines(actual);
    std::string expected_line, actual_line, difference;
    for (int number = 1; difference.empty(); ++number) {
      const bool more_expected = bool(std::getline(expected_lines, expected_line));
      const bool more_actual = bool(std::getline(actual_lines, actual_line));
      if (!more_expected && !more_actual) break;
      if (!more_expected || !more_actual || expected_line != actual_line) {
        difference = "docs/defaults.md:" + std::to_string(number) + " is\n  " +
                     (more_actual ? actual_line : "(end)") + "\nwhere the code gives\n  " +
                     (more_expected ? expected_line : "(end)") + "\n";
      }
    }
    FAIL(difference << "docs/defaults.md is out of date: run "
                       "`build/flysfm defaults > docs/defaults.md`");
  }
}

TEST_CASE("option defaults: keys are unique, values and help are not empty") {
  const std::vector<OptionDefault> defaults = ListOptionDefaults();
  std::set<std::string> keys;
  for (const OptionDefault& entry : defaults) {
    INFO(entry.key);
    CHECK(keys.insert(entry.key).second);
    CHECK(!entry.value.empty());
    CHECK(!entry.help.empty());
  }
  // Each root the page promises has its table.
  for (const char* root : {"engine", "checkpoint", "camfi", "camfi_emulator", "watch",
                           "merged_source", "view", "retrieval_training", "synthetic_capture"}) {
    INFO(root);
    CHECK(std::any_of(keys.begin(), keys.end(), [&](const std::string& key) {
      return key.rfind(std::string(root) + ".", 0) == 0;
    }));
  }
}

TEST_CASE("option defaults are read from the structs, lambda initialisers included") {
  const std::vector<OptionDefault> defaults = ListOptionDefaults();
  const Engine::Options options;
  const auto value_of = [&](const std::string& key) {
    const OptionDefault* entry = Find(defaults, key);
    INFO(key);
    REQUIRE(entry != nullptr);
    return entry->value;
  };
  CHECK(value_of("engine.max_verified_pairs") == std::to_string(options.max_verified_pairs));
  CHECK(value_of("engine.ba_tree.top_n") == std::to_string(options.ba_tree.top_n));
  CHECK(value_of("engine.refinement.pairs_per_slice") ==
        std::to_string(options.refinement.pairs_per_slice));
  // The engine's local BA overrides BundleAdjuster::Options' iterations;
  // the page must show the engine's, not the struct's own.
  CHECK(value_of("engine.local_ba.max_num_iterations") ==
        std::to_string(options.local_ba.max_num_iterations));
  CHECK(value_of("engine.global_ba.max_num_iterations") ==
        std::to_string(options.global_ba.max_num_iterations));
  CHECK(options.local_ba.max_num_iterations != BundleAdjuster::Options().max_num_iterations);
  CHECK(value_of("engine.global_ba.refine_readout_time") ==
        (options.global_ba.refine_readout_time ? "true" : "false"));
  CHECK(value_of("engine.local_ba.refine_readout_time") ==
        (options.local_ba.refine_readout_time ? "true" : "false"));
  // The triangulation RANSAC bound is TriangulationOptions' own initialiser.
  CHECK(value_of("engine.triangulation.triangulation.ransac.max_iterations") ==
        std::to_string(options.triangulation.triangulation.ransac.max_iterations));
  CHECK(value_of("engine.triangulation.triangulation.ransac.max_iterations") !=
        value_of("engine.verification.two_view.ransac.max_iterations"));
}

TEST_CASE("marker scanner: right value, wrong value, unknown key, missing value") {
  const std::vector<OptionDefault> defaults = {
      {"engine.max_verified_pairs", "8", "pairs"},
      {"camfi.password", "\"\"", "password"},
  };
  const std::string sample =
      "# Sample\n"
      "Matching stops at `8`<!-- default engine.max_verified_pairs --> verified pairs,\n"
      "or `9` <!-- default engine.max_verified_pairs --> when misquoted.\n"
      "An unknown one: `3`<!--default engine.no_such_option-->.\n"
      "No span: 8 <!-- default engine.max_verified_pairs -->\n"
      "Double fence and padding: `` \"\" ``<!-- default camfi.password -->\n";

  const std::vector<DefaultMarker> markers = FindDefaultMarkers(sample);
  REQUIRE(markers.size() == 5);
  CHECK(markers[0].line == 2);
  CHECK(markers[0].key == "engine.max_verified_pairs");
  CHECK(markers[0].value == "8");
  CHECK(markers[1].value == "9");
  CHECK(markers[2].key == "engine.no_such_option");
  CHECK(markers[2].value == "3");
  CHECK_FALSE(markers[3].has_value);
  CHECK(markers[4].value == "\"\"");

  const std::vector<std::string> problems = CheckDefaultMarkers(sample, "sample.md", defaults);
  REQUIRE(problems.size() == 3);
  CHECK(problems[0].rfind("sample.md:3: ", 0) == 0);
  CHECK(problems[0].find("`9`") != std::string::npos);
  CHECK(problems[0].find("`8`") != std::string::npos);
  CHECK(problems[1].rfind("sample.md:4: ", 0) == 0);
  CHECK(problems[1].find("engine.no_such_option") != std::string::npos);
  CHECK(problems[2].rfind("sample.md:5: ", 0) == 0);

  CHECK(CheckDefaultMarkers("`8`<!-- default engine.max_verified_pairs -->\n", "ok.md", defaults)
            .empty());
}

TEST_CASE("README.md and docs/*.md quote defaults as the code defines them") {
  const std::vector<OptionDefault> defaults = ListOptionDefaults();
  std::vector<fs::path> pages = {kSourceDir / "README.md"};
  for (const fs::directory_entry& entry : fs::directory_iterator(kSourceDir / "docs")) {
    if (entry.is_regular_file() && entry.path().extension() == ".md") {
      pages.push_back(entry.path());
    }
  }
  std::sort(pages.begin(), pages.end());
  int num_markers = 0;
  for (const fs::path& page : pages) {
    const std::string text = ReadText(page);
    num_markers += static_cast<int>(FindDefaultMarkers(text).size());
    for (const std::string& problem :
         CheckDefaultMarkers(text, fs::relative(page, kSourceDir).string(), defaults)) {
      FAIL_CHECK(problem);
    }
  }
  // docs/defaults.md quotes one itself: the scan reached the pages.
  CHECK(num_markers >= 1);
}

}  // namespace
}  // namespace flysfm
