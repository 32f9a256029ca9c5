#include "io/sources/watched_folder.h"

#include <fstream>
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

TEST_CASE("WatchedFolderOptions::Check") {
  WatchedFolderOptions options;
  CHECK(options.Check());
  options.give_up_seconds = options.stable_seconds;
  CHECK_FALSE(options.Check());
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

}  // namespace
}  // namespace flysfm
