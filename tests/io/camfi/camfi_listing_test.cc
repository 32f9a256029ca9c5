#include "io/camfi/camfi_listing.h"

#include <catch2/catch.hpp>

namespace flysfm {
namespace {

constexpr int kDepth = 64;

TEST_CASE("ParseFilesPage takes a JSON array of strings and nothing else") {
  std::string problem;
  const auto page = ParseFilesPage(R"(["/a.JPG","/b.JPG"])", kDepth, &problem);
  REQUIRE(page);
  CHECK(*page == std::vector<std::string>{"/a.JPG", "/b.JPG"});
  CHECK_FALSE(ParseFilesPage("<html>camera busy</html>", kDepth, &problem));
  CHECK(problem == "not JSON");
  CHECK_FALSE(ParseFilesPage(R"({"message":"camera busy"})", kDepth, &problem));
  CHECK(problem == "not a JSON array");
  CHECK_FALSE(ParseFilesPage(R"(["/a.JPG",1])", kDepth, &problem));
  CHECK_FALSE(ParseFilesPage(R"(["/a.JPG")", kDepth, &problem));
  // A bracket inside a string is not nesting.
  CHECK(ParseFilesPage(R"(["/[[[[.JPG"])", 1, &problem));
  const std::string deep = std::string(100000, '[') + std::string(100000, ']');
  CHECK_FALSE(ParseFilesPage(deep, kDepth, &problem));
  CHECK_THAT(problem, Catch::Contains("deeper than 64"));
}

TEST_CASE("FilesListing pages past short pages until an empty one") {
  FilesListing listing(100);
  CHECK(listing.next_start() == 0);
  // A device that pages by 2 whatever was asked.
  CHECK(listing.Add({"/a", "/b"}));
  CHECK(listing.next_start() == 2);
  CHECK(listing.Add({"/c", "/d"}));
  CHECK(listing.Add({"/e"}));
  CHECK(listing.next_start() == 5);
  CHECK_FALSE(listing.Add({}));
  CHECK_FALSE(listing.truncated());
  CHECK(listing.paths() == std::vector<std::string>{"/a", "/b", "/c", "/d", "/e"});
}

TEST_CASE("FilesListing ends when a device ignores start") {
  FilesListing listing(100);
  CHECK(listing.Add({"/a", "/b"}));
  CHECK_FALSE(listing.Add({"/a", "/b"}));
  CHECK_FALSE(listing.truncated());
  CHECK(listing.paths().size() == 2);
}

TEST_CASE("FilesListing stops at its page bound") {
  FilesListing listing(3);
  CHECK(listing.Add({"/1"}));
  CHECK(listing.Add({"/2"}));
  CHECK_FALSE(listing.Add({"/3"}));
  CHECK(listing.truncated());
  CHECK(listing.paths().size() == 3);
}

}  // namespace
}  // namespace flysfm
