// `flysfm live --camfi` as a process against the emulator: a clean stop on
// SIGINT, and a SIGKILL followed by a restart on the same --out; the same
// with watched folders, one and several; two transmitters into one model.

#include <algorithm>
#include <map>
#include <regex>
#include <set>

#include <catch2/catch.hpp>
#include <nlohmann/json.hpp>

#include "io/camfi/camfi_client.h"
#include "io/camfi/camfi_emulator.h"
#include "io/sources/image_markers.h"
#include "tests/io/sources/source_fixture.h"
#include "tests/io/camfi/camfi_fixture.h"
#include "tests/testing/temp_dir.h"
#include "tests/tools/live_process.h"

namespace flysfm {
namespace {

constexpr int kShots = 10;

std::vector<std::string> LiveArgs(const CamfiEmulator& emulator,
                                  const std::filesystem::path& out) {
  return {"live",         "--camfi",
          "127.0.0.1:" + std::to_string(emulator.http_port()),
          "--camfi-events-port", std::to_string(emulator.event_port()),
          "--camfi-reconcile-seconds", "0.5",
          "--out",        out.string()};
}

std::set<std::string> LoggedNames(const std::filesystem::path& out) {
  std::set<std::string> names;
  for (const std::string& line : testing::LinesStartingWith(out / "log.jsonl", "{")) {
    names.insert(nlohmann::json::parse(line)["name"].get<std::string>());
  }
  return names;
}

TEST_CASE("live: SIGINT ends the run cleanly with every received shot processed") {
  const std::filesystem::path dir = testing::MakeTempDir("live_sigint");
  CamfiEmulator emulator(
      testing::LoopbackEmulator(testing::WriteTestJpegs(dir / "shots", kShots), 0.3));
  const std::filesystem::path out = dir / "out";
  const pid_t pid = testing::SpawnFlysfm(LiveArgs(emulator, out), dir / "live.txt");
  const std::filesystem::path journal = out / "images" / "journal.tsv";
  REQUIRE(testing::WaitUntil(
      [&] { return testing::LinesStartingWith(journal, "stored\t").size() >= 3; }, 20));
  ::kill(pid, SIGINT);
  CHECK(testing::WaitForExit(pid, 20) == 0);
  const std::size_t received = testing::LinesStartingWith(journal, "stored\t").size();
  const nlohmann::json summary = nlohmann::json::parse(testing::ReadText(out / "summary.json"));
  CHECK(summary["images_in"].get<std::size_t>() == received);
  CHECK(LoggedNames(out).size() == received);
  CHECK(std::filesystem::exists(out / "sparse"));
}

TEST_CASE("live: after SIGKILL a restart loses nothing and fetches nothing twice") {
  const std::filesystem::path dir = testing::MakeTempDir("live_sigkill");
  const std::vector<std::filesystem::path> images =
      testing::WriteTestJpegs(dir / "shots", kShots);
  CamfiEmulator emulator(testing::LoopbackEmulator(images, 0.3));
  const std::filesystem::path out = dir / "out";
  const std::filesystem::path journal = out / "images" / "journal.tsv";
  const pid_t first = testing::SpawnFlysfm(LiveArgs(emulator, out), dir / "first.txt");
  REQUIRE(testing::WaitUntil(
      [&] { return testing::LinesStartingWith(journal, "stored\t").size() >= 3; }, 20));
  ::kill(first, SIGKILL);
  REQUIRE(testing::WaitForExit(first, 5) == 128 + SIGKILL);
  const std::vector<std::string> stored_before = testing::LinesStartingWith(journal, "stored\t");
  const std::size_t requests_before = emulator.RequestLog().size();

  std::vector<std::string> args = LiveArgs(emulator, out);
  args.insert(args.end(), {"--max-images", std::to_string(kShots)});
  const pid_t second = testing::SpawnFlysfm(args, dir / "second.txt");
  REQUIRE(testing::WaitForExit(second, 40) == 0);

  const std::vector<std::string> stored = testing::LinesStartingWith(journal, "stored\t");
  CHECK(stored.size() == std::size_t(kShots));
  // A shot stored before the kill is never requested again.
  const std::vector<std::string> log = emulator.RequestLog();
  for (const std::string& line : stored_before) {
    const std::string device_path = line.substr(7, line.find('\t', 7) - 7);
    const std::string request = "GET /raw/" + EncodeDevicePath(device_path);
    CHECK(std::find(log.begin() + std::ptrdiff_t(requests_before), log.end(), request) ==
          log.end());
  }
  std::set<std::string> names;
  for (int i = 0; i < kShots; ++i) {
    const std::string name = StoreNameForDevicePath(emulator.DevicePath(i));
    names.insert(name);
    CHECK(ReadFileBytes(out / "images" / name) == ReadFileBytes(images[std::size_t(i)]));
  }
  CHECK(LoggedNames(out) == names);
  // The second run re-fed what the first had stored, then went on live.
  std::smatch match;
  const std::string output = testing::ReadText(dir / "second.txt");
  REQUIRE(std::regex_search(output, match, std::regex("camfi: (\\d+) stored, (\\d+) replayed")));
  CHECK(std::stoul(match[2]) >= stored_before.size());
  CHECK(std::stoul(match[1]) + std::stoul(match[2]) == std::size_t(kShots));
}

// The image names of the result lines ("[   1] name  status ...") in order.
std::vector<std::string> ResultNames(const std::filesystem::path& output) {
  std::vector<std::string> names;
  const std::regex line("^\\[ *\\d+\\] (\\S+) ");
  std::ifstream in(output);
  std::smatch match;
  for (std::string text; std::getline(in, text);) {
    if (std::regex_search(text, match, line)) names.push_back(match[1]);
  }
  return names;
}

TEST_CASE("live --watch: after SIGKILL a restart resumes, re-feeding in arrival order") {
  const std::filesystem::path dir = testing::MakeTempDir("live_watch");
  const std::vector<std::filesystem::path> images = testing::WriteTestJpegs(dir / "shots", 3);
  const std::filesystem::path inbox = dir / "inbox";
  const std::filesystem::path out = dir / "out";
  std::filesystem::create_directories(inbox);
  const std::vector<std::string> args = {"live", "--watch", inbox.string(),
                                         "--watch-stable-seconds", "0.2", "--out", out.string()};
  const pid_t first = testing::SpawnFlysfm(args, dir / "first.txt");
  // Arrival order b, a: not the names' order.
  for (const auto& [image, name] : {std::pair{images[0], "b.jpg"}, std::pair{images[1], "a.jpg"}}) {
    const std::size_t before = testing::LinesStartingWith(out / "log.jsonl", "{").size();
    std::filesystem::copy_file(image, inbox / name);
    REQUIRE(testing::WaitUntil(
        [&] { return testing::LinesStartingWith(out / "log.jsonl", "{").size() > before; }, 20));
  }
  ::kill(first, SIGKILL);
  REQUIRE(testing::WaitForExit(first, 5) == 128 + SIGKILL);
  // Shot while the program was down.
  std::filesystem::copy_file(images[2], inbox / "c.jpg");

  std::vector<std::string> restart = args;
  restart.insert(restart.end(), {"--max-images", "3"});
  const pid_t second = testing::SpawnFlysfm(restart, dir / "second.txt");
  REQUIRE(testing::WaitForExit(second, 30) == 0);
  // The model resumed holds b (its snapshot followed the first image), and
  // a when a snapshot followed it too: the restart feeds the rest, in the
  // order the files arrived.
  const std::string output = testing::ReadText(dir / "second.txt");
  CHECK_THAT(output, Catch::Contains("resumed: "));
  std::vector<std::string> names = ResultNames(dir / "second.txt");
  names.erase(std::unique(names.begin(), names.end()), names.end());
  const std::vector<std::string> arrival = {"b.jpg", "a.jpg", "c.jpg"};
  REQUIRE(!names.empty());
  REQUIRE(names.size() <= 2);
  CHECK(std::equal(names.begin(), names.end(), arrival.end() - std::ptrdiff_t(names.size())));
  // The log goes on: the first run's records, then the second's.
  CHECK(testing::LinesStartingWith(out / "log.jsonl", "{").size() >= 3);
}

TEST_CASE("live --camfi A --camfi B: two transmitters into one model, each shot tagged and stored apart") {
  const std::filesystem::path dir = testing::MakeTempDir("live_two_camfi");
  const std::vector<std::filesystem::path> images = testing::WriteTestJpegs(dir / "shots", 8);
  const std::vector<std::filesystem::path> first_half(images.begin(), images.begin() + 4);
  const std::vector<std::filesystem::path> second_half(images.begin() + 4, images.end());
  CamfiEmulator alice(testing::LoopbackEmulator(first_half, 0.3));
  CamfiEmulator bob(testing::LoopbackEmulator(second_half, 0.3));
  const std::filesystem::path out = dir / "out";
  std::vector<std::string> args = {"live", "--out", out.string(), "--camfi-reconcile-seconds",
                                   "0.5", "--camfi-events-port",
                                   std::to_string(alice.event_port()), "--camfi-events-port",
                                   std::to_string(bob.event_port())};
  for (const CamfiEmulator* emulator : {&alice, &bob}) {
    args.insert(args.end(), {"--camfi", "127.0.0.1:" + std::to_string(emulator->http_port())});
  }
  const pid_t pid = testing::SpawnFlysfm(args, dir / "live.txt");
  // The same host twice: the second source's tag is made unique.
  const std::vector<std::string> tags = {"camfi-127.0.0.1", "camfi-127.0.0.1-2"};
  REQUIRE(testing::WaitUntil([&] { return LoggedNames(out).size() >= images.size(); }, 60));
  ::kill(pid, SIGINT);
  REQUIRE(testing::WaitForExit(pid, 20) == 0);

  std::map<std::string, int> logged_by_tag;
  for (const std::string& line : testing::LinesStartingWith(out / "log.jsonl", "{")) {
    const nlohmann::json record = nlohmann::json::parse(line);
    const std::string name = record["name"];
    const std::string tag = name.substr(0, name.find('/'));
    CHECK(record["source"] == tag);
    ++logged_by_tag[tag];
  }
  CHECK(logged_by_tag == std::map<std::string, int>{{tags[0], 4}, {tags[1], 4}});
  // Each transmitter its own store and journal.
  for (const std::string& tag : tags) {
    CHECK(testing::LinesStartingWith(out / "sources" / tag / "images" / "journal.tsv", "stored\t")
              .size() == 4);
  }
  const nlohmann::json summary = nlohmann::json::parse(testing::ReadText(out / "summary.json"));
  REQUIRE(summary["sources"].size() == 2);
  CHECK(summary["sources"][0]["tag"] == tags[0]);
  CHECK(summary["sources"][1]["tag"] == tags[1]);
  CHECK(summary["images_in"] == 8);
}

TEST_CASE("live --watch A --watch B: each photographer's images tagged, stored apart, resumed") {
  const std::filesystem::path dir = testing::MakeTempDir("live_sources");
  const std::vector<std::filesystem::path> images = testing::WriteTestJpegs(dir / "shots", 5);
  const std::filesystem::path alice = dir / "alice";
  const std::filesystem::path bob = dir / "bob";
  const std::filesystem::path out = dir / "out";
  std::filesystem::create_directories(alice);
  std::filesystem::create_directories(bob / "sub");
  const std::vector<std::string> args = {"live",  "--watch", alice.string(), "--watch",
                                         bob.string(), "--watch-stable-seconds", "0.2",
                                         "--out", out.string()};
  const pid_t first = testing::SpawnFlysfm(args, dir / "first.txt");
  // Both shoot an x.jpg: two images.
  const std::vector<std::pair<std::filesystem::path, std::string>> drops = {
      {alice / "x.jpg", "alice/x.jpg"},
      {bob / "x.jpg", "bob/x.jpg"},
      {alice / "y.jpg", "alice/y.jpg"},
      {bob / "sub" / "z.jpg", "bob/sub/z.jpg"}};
  for (std::size_t i = 0; i < drops.size(); ++i) {
    std::filesystem::copy_file(images[i], drops[i].first);
  }
  REQUIRE(testing::WaitUntil([&] { return LoggedNames(out).size() >= drops.size(); }, 30));
  ::kill(first, SIGINT);
  REQUIRE(testing::WaitForExit(first, 20) == 0);

  std::set<std::string> expected;
  for (const auto& [file, name] : drops) expected.insert(name);
  CHECK(LoggedNames(out) == expected);
  for (const std::string& line : testing::LinesStartingWith(out / "log.jsonl", "{")) {
    const nlohmann::json record = nlohmann::json::parse(line);
    const std::string name = record["name"];
    CHECK(record["source"] == name.substr(0, name.find('/')));
  }
  const nlohmann::json summary = nlohmann::json::parse(testing::ReadText(out / "summary.json"));
  REQUIRE(summary["sources"].size() == 2);
  CHECK(summary["sources"][0]["tag"] == "alice");
  CHECK(summary["sources"][0]["images_in"] == 2);
  CHECK(summary["sources"][1]["tag"] == "bob");
  CHECK(summary["sources"][1]["images_in"] == 2);
  int registered = 0, rejected = 0, pending = 0;
  for (const nlohmann::json& source : summary["sources"]) {
    registered += source["registered"].get<int>();
    rejected += source["rejected"].get<int>();
    pending += source["pending"].get<int>();
  }
  CHECK(registered == summary["registered"]);
  CHECK(rejected == summary["rejected"]);
  CHECK(pending == int(summary["pending"].size()));
  // Each folder's own state, with its own files only.
  for (const char* tag : {"alice", "bob"}) {
    const std::filesystem::path state = out / "sources" / tag / "watched.tsv";
    CHECK(testing::LinesStartingWith(state, "").size() == 2);
  }
  CHECK_FALSE(std::filesystem::exists(out / "watched.tsv"));

  // Shot while the program was down; the restart re-feeds both folders'
  // files from their states, skips them (the model holds them) and takes
  // the new one only.
  std::filesystem::copy_file(images[4], bob / "w.jpg");
  std::vector<std::string> restart = args;
  restart.insert(restart.end(), {"--max-images", "5"});
  const pid_t second = testing::SpawnFlysfm(restart, dir / "second.txt");
  REQUIRE(testing::WaitForExit(second, 30) == 0);
  CHECK_THAT(testing::ReadText(dir / "second.txt"), Catch::Contains("resumed: 4 images"));
  std::vector<std::string> names = ResultNames(dir / "second.txt");
  names.erase(std::unique(names.begin(), names.end()), names.end());
  CHECK(names == std::vector<std::string>{"bob/w.jpg"});
}

}  // namespace
}  // namespace flysfm
