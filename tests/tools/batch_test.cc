// `flysfm batch` as a process: several photographers' folders interleaved
// by EXIF capture time or in turn, their images named <tag>/<name>, every
// record and the summary telling each image's source; one folder as before.

#include <algorithm>
#include <cstdio>
#include <fstream>
#include <map>
#include <set>
#include <string>
#include <vector>

#include <catch2/catch.hpp>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>

#include "tests/io/sources/source_fixture.h"
#include "tests/testing/exif_jpeg.h"
#include "tests/testing/rendered_capture.h"
#include "tests/testing/sanitizer.h"
#include "tests/testing/temp_dir.h"
#include "tests/tools/live_process.h"

namespace flysfm {
namespace {

namespace fs = std::filesystem;

// The rendered walk's views 0-9: photographer A shot 0, 1, 4, 5, 8, 9 and
// B 2, 3, 6, 7 (8 views under a sanitizer: A 0, 1, 4, 5; B 2, 3, 6, 7).
SyntheticCapture Capture() {
  SyntheticCaptureOptions options;
  options.num_views = testing::kSanitizerBuild ? 8 : 10;  // tests/testing/sanitizer.h
  options.seed = 4;
  return testing::RenderedCapture(options);
}
bool ShotByA(std::size_t view) { return view % 4 < 2; }

// Each view written into its photographer's folder, `<root>/<n>/shots`
// (both folders are "shots": their tags become "shots" and "shots-2").
// With `exif`: a JPEG whose DateTimeOriginal is one second per view in
// walk order, named so that name order is the reverse of it. Without: the
// capture's PNG under its own name. Returns each view's image name as the
// run must call it.
std::vector<std::string> WriteFolders(const SyntheticCapture& capture, const fs::path& root,
                                      bool exif) {
  std::vector<std::string> names;
  for (std::size_t view = 0; view < capture.frames.size(); ++view) {
    const bool a = ShotByA(view);
    const fs::path folder = root / (a ? "1" : "2") / "shots";
    fs::create_directories(folder);
    std::string file = capture.frames[view].name;
    std::vector<std::uint8_t> bytes = capture.frames[view].bytes;
    if (exif) {
      char name[32], time[32];
      std::snprintf(name, sizeof(name), "IMG_%04zu.JPG", 100 - view);
      std::snprintf(time, sizeof(time), "2024:05:17 10:00:%02zu", view);
      file = name;
      testing::ExifTags tags;
      tags.texts = {{EXIF_TAG_DATE_TIME_ORIGINAL, time}, {EXIF_TAG_SUB_SEC_TIME_ORIGINAL, "25"}};
      bytes = testing::JpegWithExif(cv::imdecode(bytes, cv::IMREAD_COLOR), tags);
    }
    std::ofstream(folder / file, std::ios::binary)
        .write(reinterpret_cast<const char*>(bytes.data()), std::streamsize(bytes.size()));
    names.push_back((a ? "shots/" : "shots-2/") + file);
  }
  return names;
}

std::vector<std::string> BatchArgs(const fs::path& root, const fs::path& out) {
  return {"batch",    (root / "1" / "shots").string(), (root / "2" / "shots").string(),
          "--camera", "PINHOLE 500,500,320,240",       "--out",
          out.string()};
}

struct Logged {
  std::vector<std::string> first_seen;        // names in the order of their first record
  std::map<std::string, std::string> source;  // name -> its records' "source"
  std::map<std::string, std::string> status;  // name -> its last record's status
};

Logged ReadLog(const fs::path& out) {
  Logged logged;
  for (const std::string& line : testing::LinesStartingWith(out / "log.jsonl", "{")) {
    const nlohmann::json record = nlohmann::json::parse(line);
    const std::string name = record["name"];
    if (logged.status.count(name) == 0) logged.first_seen.push_back(name);
    logged.source[name] = record.value("source", "");
    logged.status[name] = record["status"];
  }
  return logged;
}

nlohmann::json Summary(const fs::path& out) {
  return nlohmann::json::parse(testing::ReadText(out / "summary.json"));
}

TEST_CASE("batch A B: interleaved by EXIF capture time, every image registered, sources told") {
  const fs::path dir = testing::MakeTempDir("batch_sources");
  const SyntheticCapture capture = Capture();
  const std::vector<std::string> names = WriteFolders(capture, dir / "in", /*exif=*/true);
  const fs::path out = dir / "out";
  const pid_t pid = testing::SpawnFlysfm(BatchArgs(dir / "in", out), dir / "batch.txt");
  REQUIRE(testing::WaitForExit(pid, 120) == 0);
  CHECK_THAT(testing::ReadText(dir / "batch.txt"), Catch::Contains("by EXIF capture time"));

  const Logged logged = ReadLog(out);
  // As shot: the walk's order, across both folders and against name order.
  CHECK(logged.first_seen == names);
  std::size_t num_a = 0;
  for (std::size_t view = 0; view < names.size(); ++view) {
    INFO(names[view]);
    num_a += ShotByA(view);
    CHECK(logged.source.at(names[view]) == (ShotByA(view) ? "shots" : "shots-2"));
    CHECK(logged.status.at(names[view]) == "registered");
  }
  const nlohmann::json summary = Summary(out);
  CHECK(summary["registered"] == names.size());
  const nlohmann::json expected = nlohmann::json::array(
      {{{"tag", "shots"}, {"images_in", num_a}, {"registered", num_a}, {"rejected", 0},
        {"pending", 0}},
       {{"tag", "shots-2"}, {"images_in", names.size() - num_a},
        {"registered", names.size() - num_a}, {"rejected", 0}, {"pending", 0}}});
  CHECK(summary["sources"] == expected);
  // The model's images are named so too.
  std::ifstream images(out / "sparse" / "images.txt");
  std::set<std::string> in_model;
  for (std::string line; std::getline(images, line);) {
    for (const std::string& name : names) {
      if (line.size() > name.size() &&
          line.compare(line.size() - name.size(), name.size(), name) == 0) {
        in_model.insert(name);
      }
    }
  }
  CHECK(in_model.size() == names.size());
}

TEST_CASE("batch A B without EXIF capture times: the folders take turns, in name order") {
  const fs::path dir = testing::MakeTempDir("batch_turns");
  const SyntheticCapture capture = Capture();
  const std::vector<std::string> names = WriteFolders(capture, dir / "in", /*exif=*/false);
  const fs::path out = dir / "out";
  const pid_t pid = testing::SpawnFlysfm(BatchArgs(dir / "in", out), dir / "batch.txt");
  REQUIRE(testing::WaitForExit(pid, 120) == 0);
  CHECK_THAT(testing::ReadText(dir / "batch.txt"),
             Catch::Contains("round robin in name order") &&
                 Catch::Contains(std::to_string(names.size()) + " of " +
                                 std::to_string(names.size()) + " images have no EXIF"));
  // A's first, B's first, A's second, ...; the longer folder ends alone.
  std::vector<std::string> a, b, turns;
  for (std::size_t view = 0; view < names.size(); ++view) {
    (ShotByA(view) ? a : b).push_back(names[view]);
  }
  for (std::size_t k = 0; k < std::max(a.size(), b.size()); ++k) {
    if (k < a.size()) turns.push_back(a[k]);
    if (k < b.size()) turns.push_back(b[k]);
  }
  const Logged logged = ReadLog(out);
  CHECK(logged.first_seen == turns);
  const nlohmann::json summary = Summary(out);
  int images_in = 0;
  for (const nlohmann::json& source : summary["sources"]) images_in += source["images_in"].get<int>();
  CHECK(images_in == int(names.size()));
  CHECK(summary["images_in"] == names.size());
}

TEST_CASE("batch of one folder names its images as before, and a TUM sequence is not merged") {
  const fs::path dir = testing::MakeTempDir("batch_one");
  testing::WriteTestJpegs(dir / "shots", 3);
  const fs::path out = dir / "out";
  const pid_t pid = testing::SpawnFlysfm(
      {"batch", (dir / "shots").string(), "--out", out.string()}, dir / "batch.txt");
  REQUIRE(testing::WaitForExit(pid, 60) == 0);
  const Logged logged = ReadLog(out);
  CHECK(logged.first_seen == std::vector<std::string>{"shot00.jpg", "shot01.jpg", "shot02.jpg"});
  for (const auto& [name, source] : logged.source) CHECK(source.empty());
  CHECK_FALSE(Summary(out).contains("sources"));

  const fs::path tum = dir / "tum";
  fs::create_directories(tum);
  std::ofstream(tum / "rgb.txt") << "1.0 rgb/1.png\n";
  const pid_t refused = testing::SpawnFlysfm(
      {"batch", (dir / "shots").string(), tum.string(), "--out", (dir / "out2").string()},
      dir / "refused.txt");
  CHECK(testing::WaitForExit(refused, 60) == 2);
  CHECK_THAT(testing::ReadText(dir / "refused.txt"), Catch::Contains("is a TUM sequence"));
}

}  // namespace
}  // namespace flysfm
