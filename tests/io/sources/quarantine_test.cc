#include "io/sources/quarantine.h"

#include <fstream>

#include <catch2/catch.hpp>

#include "tests/testing/temp_dir.h"

namespace flysfm {
namespace {

namespace fs = std::filesystem;

TEST_CASE("A journal keeps any field whole and drops a line cut short") {
  const fs::path path = testing::MakeTempDir("journal") / "journal.tsv";
  const std::vector<std::string> odd = {"a\tb", "line\nbreak", "back\\slash", ""};
  {
    JournalFile journal(path);
    journal.Append(odd);
    journal.Append({"second"});
  }
  std::ofstream(path, std::ios::app) << "cut\tshort";
  const std::vector<std::vector<std::string>> records = JournalFile::Read(path);
  REQUIRE(records.size() == 2);
  CHECK(records[0] == odd);
  CHECK(records[1] == std::vector<std::string>{"second"});
  CHECK(JournalFile::Read(path.parent_path() / "none.tsv").empty());
}

void AppendRecords(const fs::path& path,
                   const std::vector<std::pair<std::string, std::string>>& records) {
  JournalFile journal(path);
  for (const auto& [kind, name] : records) journal.Append({kind, name});
}

TEST_CASE("An image open in the engine at two deaths in a row is quarantined") {
  const fs::path path = testing::MakeTempDir("quarantine") / "quarantine.tsv";
  // What a run leaves when it dies (no signal report: SIGKILL) in the engine
  // on b.jpg while c.jpg is decoded ahead.
  AppendRecords(path, {{"decode", "a.jpg"}, {"engine", "a.jpg"}, {"done", "a.jpg"},
                       {"decode", "b.jpg"}, {"engine", "b.jpg"}, {"decode", "c.jpg"}});
  {
    // A kill is no proof against the photo: one more try.
    const Quarantine quarantine(path, /*retry=*/false);
    CHECK_FALSE(quarantine.Reason("a.jpg"));
    CHECK_FALSE(quarantine.Reason("b.jpg"));
    CHECK_FALSE(quarantine.Reason("c.jpg"));
  }
  AppendRecords(path, {{"decode", "b.jpg"}, {"engine", "b.jpg"}});
  {
    const Quarantine quarantine(path, /*retry=*/false);
    REQUIRE(quarantine.Reason("b.jpg"));
    CHECK_THAT(*quarantine.Reason("b.jpg"), Catch::Contains("2 times"));
    CHECK_FALSE(quarantine.Reason("c.jpg"));
  }
  {
    const Quarantine quarantine(path, /*retry=*/true);
    CHECK_FALSE(quarantine.Reason("b.jpg"));
  }
  // After a retry the count starts again.
  AppendRecords(path, {{"engine", "b.jpg"}});
  const Quarantine quarantine(path, /*retry=*/false);
  CHECK_FALSE(quarantine.Reason("b.jpg"));
}

TEST_CASE("A crash report quarantines its image at once, the others open are innocent") {
  const fs::path path = testing::MakeTempDir("quarantine_crash") / "quarantine.tsv";
  AppendRecords(path, {{"decode", "a.jpg"}, {"engine", "a.jpg"}, {"decode", "b.jpg"},
                       {"crashed", "a.jpg"}});
  {
    Quarantine quarantine(path, /*retry=*/false);
    CHECK(quarantine.Reason("a.jpg"));
    CHECK_FALSE(quarantine.Reason("b.jpg"));
    quarantine.BeginDecode("d.jpg");
    quarantine.BeginEngine("d.jpg");
    quarantine.Fail("d.jpg", "engine error: boom");
    // Left open when the run ends normally: not blamed at the next start.
    quarantine.BeginDecode("e.jpg");
  }
  const Quarantine quarantine(path, /*retry=*/false);
  CHECK(quarantine.Reason("a.jpg"));
  CHECK_FALSE(quarantine.Reason("b.jpg"));
  CHECK(quarantine.Reason("d.jpg") == std::optional<std::string>("engine error: boom"));
  CHECK_FALSE(quarantine.Reason("e.jpg"));
}

TEST_CASE("An image being decoded at two deaths, none in the engine, is quarantined") {
  const fs::path path = testing::MakeTempDir("quarantine_decode") / "quarantine.tsv";
  AppendRecords(path, {{"decode", "a.jpg"}});
  CHECK_FALSE(Quarantine(path, /*retry=*/false).Reason("a.jpg"));
  AppendRecords(path, {{"decode", "a.jpg"}});
  CHECK(Quarantine(path, /*retry=*/false).Reason("a.jpg"));
}

TEST_CASE("The filter hands on all but the quarantined frames") {
  const fs::path path = testing::MakeTempDir("quarantine_filter") / "quarantine.tsv";
  std::vector<Frame> frames(3);
  for (int i = 0; i < 3; ++i) frames[std::size_t(i)].name = "f" + std::to_string(i);
  Quarantine quarantine(path, /*retry=*/false);
  quarantine.Fail("f1", "engine error");
  FrameListSource source(frames);
  QuarantineFilterSource filtered(&source, &quarantine);
  std::vector<std::string> names;
  while (std::optional<Frame> frame = filtered.Next()) names.push_back(frame->name);
  CHECK(names == std::vector<std::string>{"f0", "f2"});
  CHECK(filtered.num_skipped() == 1);
}

}  // namespace
}  // namespace flysfm
