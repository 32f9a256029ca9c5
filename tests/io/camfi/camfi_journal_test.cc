#include "io/camfi/camfi_journal.h"

#include <cerrno>
#include <fstream>
#include <sstream>

#include <catch2/catch.hpp>

#include "tests/testing/temp_dir.h"

namespace flysfm {
namespace {

const std::string kSha1(40, 'a');

std::string ReadText(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream text;
  text << in.rdbuf();
  return text.str();
}

void WriteText(const std::filesystem::path& path, const std::string& text) {
  std::ofstream(path, std::ios::binary) << text;
}

TEST_CASE("Journal fields carry tabs, newlines, '%' and backslashes without splitting a record") {
  const std::string hostile = "/store_00010001/DCIM/a\tb\nstored\tx\ty\t1\r%41\\.JPG";
  const std::string text =
      FormatJournalRecord(JournalRecord::Stored(hostile, "name.JPG", 7, kSha1)) +
      FormatJournalRecord(JournalRecord::Ignored(hostile));
  // One line per record: no raw tab or newline inside a field.
  CHECK(std::count(text.begin(), text.end(), '\n') == 2);
  const JournalContents contents = ParseJournal(text);
  CHECK(contents.skipped.empty());
  REQUIRE(contents.records.size() == 2);
  CHECK(contents.records[0].device_path == hostile);
  CHECK(contents.records[0].store_name == "name.JPG");
  CHECK(contents.records[0].bytes == 7);
  CHECK(contents.records[0].sha1 == kSha1);
  CHECK(contents.records[1].device_path == hostile);
  CHECK(UnescapeJournalField(EscapeJournalField(hostile)) == hostile);
  CHECK_FALSE(UnescapeJournalField("%4"));
  CHECK_FALSE(UnescapeJournalField("%G1"));
}

TEST_CASE("A malformed journal record is skipped and counted, the rest is read") {
  const std::string text =
      "baseline\n"
      "stored\t/a.JPG\ta.JPG\tabc\t" +
      kSha1 +
      "\n"                                                // bad number
      "stored\t/b.JPG\tb.JPG\t99999999999999999999999\n"  // overflow
      "stored\t/c.JPG\t../c.JPG\t5\n"                     // leaves the store
      "stored\t/d.JPG\td.JPG\t5\tnot-a-hash\n"
      "ignored\t/e%ZZ.JPG\n"  // bad escape
      "something else\n"
      "stored\t/f.JPG\tf.JPG\t5\n"  // before the hash
      "ignored\t/g.JPG\n";
  const JournalContents contents = ParseJournal(text);
  CHECK(contents.skipped.size() == 6);
  CHECK(contents.skipped[0].rfind("line 2:", 0) == 0);
  REQUIRE(contents.records.size() == 3);
  CHECK(contents.records[0].kind == JournalRecord::Kind::kBaseline);
  CHECK(contents.records[1].device_path == "/f.JPG");
  CHECK(contents.records[1].sha1.empty());
  CHECK(contents.records[2].device_path == "/g.JPG");
  CHECK(contents.complete_bytes == text.size());
}

TEST_CASE("A torn last journal line is cut off before the next append") {
  const std::filesystem::path dir = testing::MakeTempDir("camfi_journal_torn");
  const std::filesystem::path path = dir / "journal.tsv";
  const std::string complete = FormatJournalRecord(JournalRecord::Baseline()) +
                               FormatJournalRecord(JournalRecord::Ignored("/a.JPG"));
  WriteText(path, complete + "stored\t/b.JPG\tb.J");
  {
    JournalContents contents;
    std::size_t torn = 0;
    CamfiJournalFile journal(path, nullptr, &contents, &torn);
    CHECK(torn == std::string("stored\t/b.JPG\tb.J").size());
    CHECK(contents.records.size() == 2);
    CHECK(ReadText(path) == complete);
    std::string error;
    REQUIRE(journal.Append(FormatJournalRecord(JournalRecord::Ignored("/c.JPG")), &error));
  }
  const JournalContents again = ParseJournal(ReadText(path));
  CHECK(again.skipped.empty());
  REQUIRE(again.records.size() == 3);
  CHECK(again.records[2].device_path == "/c.JPG");
}

TEST_CASE("A journal append on a full disk leaves no half record, and the next one works") {
  const std::filesystem::path dir = testing::MakeTempDir("camfi_journal_full");
  const std::filesystem::path path = dir / "journal.tsv";
  bool full = true;
  JournalContents contents;
  std::size_t torn = 0;
  CamfiJournalFile journal(
      path, [&](const std::filesystem::path&) { return full ? ENOSPC : 0; }, &contents, &torn);
  std::string error;
  CHECK_FALSE(journal.Append(FormatJournalRecord(JournalRecord::Ignored("/a.JPG")), &error));
  CHECK_THAT(error, Catch::Contains("No space left"));
  CHECK(ReadText(path).empty());
  full = false;
  REQUIRE(journal.Append(FormatJournalRecord(JournalRecord::Ignored("/b.JPG")), &error));
  const JournalContents after = ParseJournal(ReadText(path));
  CHECK(after.skipped.empty());
  REQUIRE(after.records.size() == 1);
  CHECK(after.records[0].device_path == "/b.JPG");
}

}  // namespace
}  // namespace flysfm
