#include "io/sources/watched_folder.h"

#include <fstream>
#include <iostream>
#include <sstream>
#include <thread>

#include <catch2/catch.hpp>

#include "io/sources/image_markers.h"
#include "matching/image_decode.h"
#include "tests/io/sources/source_fixture.h"
#include "tests/testing/temp_dir.h"

namespace flysfm {
namespace {

WatchedFolderOptions FastOptions() {
  WatchedFolderOptions options;
  options.poll_seconds = 0.05;
  options.stable_seconds = 0.2;
  options.give_up_seconds = 0.8;
  return options;
}

// Appends `bytes` to `path` in `chunks` pieces, pausing between them longer
// than the stability time, as a slow upload does.
void WriteSlowly(const std::filesystem::path& path, const std::vector<std::uint8_t>& bytes,
                 int chunks, int pause_ms) {
  std::ofstream out(path, std::ios::binary);
  const std::size_t step = (bytes.size() + std::size_t(chunks) - 1) / std::size_t(chunks);
  for (std::size_t offset = 0; offset < bytes.size(); offset += step) {
    const std::size_t size = std::min(step, bytes.size() - offset);
    out.write(reinterpret_cast<const char*>(bytes.data() + offset), std::streamsize(size));
    out.flush();
    std::this_thread::sleep_for(std::chrono::milliseconds(pause_ms));
  }
}

// What the source writes to std::cerr while this object lives.
class CerrCapture {
 public:
  CerrCapture() : previous_(std::cerr.rdbuf(text_.rdbuf())) {}
  ~CerrCapture() { std::cerr.rdbuf(previous_); }
  std::string text() const { return text_.str(); }

 private:
  std::stringstream text_;
  std::streambuf* previous_;
};

int Occurrences(const std::string& text, const std::string& part) {
  int count = 0;
  for (std::size_t at = text.find(part); at != std::string::npos; at = text.find(part, at + 1)) {
    ++count;
  }
  return count;
}

TEST_CASE("WatchedFolderOptions::Check") {
  WatchedFolderOptions options;
  CHECK(options.Check());
  // A field photographer expects every photo below the folder to count.
  CHECK(options.recursive);
  options.give_up_seconds = options.stable_seconds;
  std::string error;
  CHECK_FALSE(options.Check(&error));
  CHECK_THAT(error, Catch::Contains("give_up_seconds"));
  CHECK_THROWS_AS(WatchedFolderSource("/no/such/folder", WatchedFolderOptions()),
                  std::invalid_argument);
}

TEST_CASE("Files written slowly are handed on whole and once each in arrival order") {
  const std::filesystem::path dir = testing::MakeTempDir("watch");
  const std::filesystem::path shots = dir / "shots";
  const std::filesystem::path inbox = dir / "inbox";
  std::filesystem::create_directories(inbox);
  const std::vector<std::filesystem::path> images = testing::WriteTestJpegs(shots, 4);
  WatchedFolderSource source(inbox, FastOptions());
  std::thread writer([&] {
    // Reverse name order: the order of arrival, not of names, counts.
    for (int i = 3; i >= 0; --i) {
      WriteSlowly(inbox / ("in_" + images[std::size_t(i)].filename().string()),
                  ReadFileBytes(images[std::size_t(i)]), 4, 300);
    }
  });
  const std::vector<Frame> frames =
      testing::PullFrames(&source, [&] { source.Stop(); }, 5, 8);
  writer.join();
  REQUIRE(frames.size() == 4);
  for (int k = 0; k < 4; ++k) {
    const Frame& frame = frames[std::size_t(k)];
    CHECK(frame.name == "in_" + images[std::size_t(3 - k)].filename().string());
    // The bytes handed on are the complete file, and they decode.
    CHECK(frame.bytes == ReadFileBytes(images[std::size_t(3 - k)]));
    CHECK(DecodeImageBytes(frame.bytes).ok());
  }
}

TEST_CASE("A file that never completes is reported and not handed on") {
  const std::filesystem::path dir = testing::MakeTempDir("watch_incomplete");
  const std::vector<std::filesystem::path> images = testing::WriteTestJpegs(dir / "shots", 2);
  std::filesystem::create_directories(dir / "inbox");
  std::vector<std::uint8_t> cut = ReadFileBytes(images[0]);
  cut.resize(cut.size() / 2);
  std::ofstream(dir / "inbox" / "cut.jpg", std::ios::binary)
      .write(reinterpret_cast<const char*>(cut.data()), std::streamsize(cut.size()));
  std::filesystem::copy_file(images[1], dir / "inbox" / "whole.jpg");
  WatchedFolderSource source(dir / "inbox", FastOptions());
  const std::vector<Frame> frames =
      testing::PullFrames(&source, [&] { source.Stop(); }, 2, 1.5);
  REQUIRE(frames.size() == 1);
  CHECK(frames[0].name == "whole.jpg");
  CHECK(source.num_incomplete() == 1);
}

TEST_CASE("A listing error is reported once, and again only when it changes") {
  const std::filesystem::path dir = testing::MakeTempDir("watch_errors");
  const std::vector<std::filesystem::path> images = testing::WriteTestJpegs(dir / "shots", 1);
  const std::filesystem::path inbox = dir / "inbox";
  std::filesystem::create_directories(inbox);
  std::filesystem::copy_file(images[0], inbox / "whole.jpg");
  std::filesystem::create_symlink("loop.jpg", inbox / "loop.jpg");
  CerrCapture captured;
  WatchedFolderSource source(inbox, FastOptions());
  // About 30 polls: the loop for the first 10, none for the next 10, then
  // another loop.
  std::thread changer([&] {
    std::this_thread::sleep_for(std::chrono::milliseconds(500));
    std::filesystem::remove(inbox / "loop.jpg");
    std::this_thread::sleep_for(std::chrono::milliseconds(500));
    std::filesystem::create_symlink("other.jpg", inbox / "other.jpg");
  });
  const std::vector<Frame> frames =
      testing::PullFrames(&source, [&] { source.Stop(); }, 2, 1.5);
  changer.join();
  REQUIRE(frames.size() == 1);
  CHECK(frames[0].name == "whole.jpg");
  CHECK(Occurrences(captured.text(), "loop.jpg") == 1);
  CHECK(Occurrences(captured.text(), "without errors again") == 1);
  CHECK(Occurrences(captured.text(), "other.jpg") == 1);
  CHECK(source.num_listing_errors() == 2);
}

TEST_CASE("Sub-folders are watched unless recursive is off, hidden entries never") {
  const std::filesystem::path dir = testing::MakeTempDir("watch_recursive");
  const std::filesystem::path inbox = dir / "inbox";
  // Two card folders with the same file names (DCIM rollover).
  testing::WriteTestJpegs(inbox / "DCIM" / "100CANON", 1, 1);
  testing::WriteTestJpegs(inbox / "DCIM" / "101CANON", 1, 2);
  testing::WriteTestJpegs(inbox / ".hidden", 1, 3);
  std::filesystem::copy_file(inbox / ".hidden" / "shot00.jpg", inbox / "._shot00.jpg");
  WatchedFolderSource source(inbox, FastOptions());
  const std::vector<Frame> frames =
      testing::PullFrames(&source, [&] { source.Stop(); }, 3, 1.0);
  REQUIRE(frames.size() == 2);
  CHECK(frames[0].name == "DCIM/100CANON/shot00.jpg");
  CHECK(frames[1].name == "DCIM/101CANON/shot00.jpg");
  CHECK(frames[0].bytes != frames[1].bytes);

  WatchedFolderOptions flat = FastOptions();
  flat.recursive = false;
  WatchedFolderSource top_only(inbox, flat);
  CHECK(testing::PullFrames(&top_only, [&] { top_only.Stop(); }, 1, 0.6).empty());
}

TEST_CASE("A file renamed or moved within the folder is not a new image") {
  const std::filesystem::path dir = testing::MakeTempDir("watch_rename");
  const std::vector<std::filesystem::path> images = testing::WriteTestJpegs(dir / "shots", 1);
  const std::filesystem::path inbox = dir / "inbox";
  std::filesystem::create_directories(inbox / "sorted");
  std::filesystem::copy_file(images[0], inbox / "IMG_0001.JPG");
  WatchedFolderSource source(inbox, FastOptions());
  REQUIRE(testing::PullFrames(&source, [&] { source.Stop(); }, 1, 2).size() == 1);
  std::filesystem::rename(inbox / "IMG_0001.JPG", inbox / "sorted" / "renamed.jpg");
  CHECK(testing::PullFrames(&source, [&] { source.Stop(); }, 1, 0.8).empty());
}

TEST_CASE("A restart hands on the files of the state file first, in their order") {
  const std::filesystem::path dir = testing::MakeTempDir("watch_state");
  const std::vector<std::filesystem::path> images = testing::WriteTestJpegs(dir / "shots", 4);
  const std::filesystem::path inbox = dir / "inbox";
  std::filesystem::create_directories(inbox);
  WatchedFolderOptions options = FastOptions();
  options.state_file = dir / "out" / "watched.tsv";
  std::filesystem::create_directories(options.state_file.parent_path());
  // Arrival order c, a, b: not the names' order.
  const std::vector<std::string> arrival = {"c.jpg", "a.jpg", "b.jpg"};
  {
    WatchedFolderSource first(inbox, options);
    for (std::size_t i = 0; i < arrival.size(); ++i) {
      std::filesystem::copy_file(images[i], inbox / arrival[i]);
      const std::vector<Frame> frames =
          testing::PullFrames(&first, [&] { first.Stop(); }, 1, 2);
      REQUIRE(frames.size() == 1);
      CHECK(frames[0].name == arrival[i]);
    }
  }
  // While the program is down: one file is renamed, one new arrives.
  std::filesystem::rename(inbox / "a.jpg", inbox / "a_renamed.jpg");
  std::filesystem::copy_file(images[3], inbox / "0_new.jpg");

  WatchedFolderSource second(inbox, options);
  const std::vector<Frame> frames =
      testing::PullFrames(&second, [&] { second.Stop(); }, 4, 3);
  REQUIRE(frames.size() == 4);
  CHECK(frames[0].name == "c.jpg");
  CHECK(frames[1].name == "a_renamed.jpg");
  CHECK(frames[1].bytes == ReadFileBytes(images[1]));
  CHECK(frames[2].name == "b.jpg");
  CHECK(frames[3].name == "0_new.jpg");
  CHECK(second.num_missing() == 0);
}

}  // namespace
}  // namespace flysfm
