#include "io/formats/atomic_file.h"

#include <fstream>
#include <sstream>
#include <stdexcept>
#include <string>

#include <catch2/catch.hpp>

#include "tests/testing/temp_dir.h"

namespace flysfm {
namespace {

std::string Contents(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

void WriteText(const std::filesystem::path& path, const std::string& text) {
  WriteFileAtomically(path, [&](std::ostream& out) { out << text; });
}

std::string FailureOf(const std::function<void()>& call) {
  try {
    call();
  } catch (const std::runtime_error& e) {
    return e.what();
  }
  return "";
}

TEST_CASE("An atomic write replaces the file and leaves no temporary") {
  const auto path = testing::MakeTempDir("atomic_file") / "model.txt";
  WriteText(path, "first");
  WriteText(path, "second");
  CHECK(Contents(path) == "second");
  CHECK_FALSE(std::filesystem::exists(path.string() + ".tmp"));
}

TEST_CASE("A failed atomic write keeps the old file, removes its temporary and says why") {
  const auto dir = testing::MakeTempDir("atomic_file_failures");
  const auto path = dir / "summary.json";
  WriteText(path, "old");

  SECTION("the stream fails half way, as on a full disk") {
    const std::string message = FailureOf([&] {
      WriteFileAtomically(path, [](std::ostream& out) {
        out << "half";
        out.setstate(std::ios::badbit);
      });
    });
    CHECK(message.find((dir / "summary.json.tmp").string()) != std::string::npos);
  }
  SECTION("the writer throws") {
    const std::string message = FailureOf([&] {
      WriteFileAtomically(path, [](std::ostream& out) {
        out << "half";
        throw std::runtime_error("no more points");
      });
    });
    CHECK(message.find("no more points") != std::string::npos);
  }
  CHECK(Contents(path) == "old");
  CHECK_FALSE(std::filesystem::exists(path.string() + ".tmp"));
}

TEST_CASE("An atomic write into a missing folder names the path and the reason") {
  const auto path = testing::MakeTempDir("atomic_file_missing") / "no" / "such.txt";
  const std::string message = FailureOf([&] { WriteText(path, "x"); });
  CHECK(message.find(path.string()) != std::string::npos);
  CHECK(message.find("No such file or directory") != std::string::npos);
}

}  // namespace
}  // namespace flysfm
