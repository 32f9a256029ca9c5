#include "io/camfi/camfi_client.h"

#include <algorithm>
#include <fstream>
#include <set>
#include <thread>

#include <catch2/catch.hpp>

#include "io/camfi/camfi_emulator.h"
#include "io/sources/image_markers.h"
#include "tests/io/camfi/camfi_fixture.h"
#include "tests/testing/temp_dir.h"

namespace flysfm {
namespace {

constexpr int kShots = 7;

CamfiEmulatorOptions FastEmulator(const std::vector<std::filesystem::path>& images) {
  CamfiEmulatorOptions options = testing::LoopbackEmulator(images, 0.1, 250, 250);
  options.fault_every = 3;
  return options;
}

CamfiOptions FastClient(const CamfiEmulator& emulator) {
  CamfiOptions options;
  options.host = "127.0.0.1";
  options.http_port = emulator.http_port();
  options.event_port = emulator.event_port();
  options.reconcile_seconds = 0.5;
  options.backoff_min_seconds = 0.1;
  options.backoff_max_seconds = 0.4;
  options.control_timeout = 2;
  options.list_timeout = 2;
  options.download_idle_seconds = 2;
  options.retries = 3;
  return options;
}

std::vector<std::string> JournalLines(const std::filesystem::path& store, const std::string& kind) {
  std::ifstream in(store / "journal.tsv");
  std::vector<std::string> lines;
  for (std::string line; std::getline(in, line);) {
    if (line.compare(0, kind.size(), kind) == 0) lines.push_back(line);
  }
  return lines;
}

int NumImageFiles(const std::filesystem::path& store) {
  int count = 0;
  for (const auto& entry : std::filesystem::directory_iterator(store)) {
    if (entry.path().extension() == ".JPG") ++count;
  }
  return count;
}

struct Outcome {
  CamfiEmulatorStats emulator;
  CamfiStats client;
};

// Runs a client against an emulator with `faults` until every shot is in
// the store, then checks what every fault must leave intact: each shot
// stored once, byte-identical, downloaded once, through %2F-encoded paths.
Outcome RunWithFaults(const std::set<CamfiFault>& faults,
                                 const std::string& password = "") {
  const std::filesystem::path dir = testing::MakeTempDir("camfi_client");
  const std::vector<std::filesystem::path> images =
      testing::WriteTestJpegs(dir, kShots, int(faults.size()) + 3);
  CamfiEmulatorOptions emulator_options = FastEmulator(images);
  emulator_options.faults = faults;
  CamfiEmulator emulator(emulator_options);
  CamfiOptions client_options = FastClient(emulator);
  client_options.password = password;
  const std::filesystem::path store = dir / "store";
  std::vector<Frame> frames;
  CamfiStats client_stats;
  {
    CamfiSource source(client_options, store);
    frames = testing::PullFrames(&source, [&] { source.Stop(); }, kShots, 15);
    // Long enough for another listing and any duplicate or late event.
    std::this_thread::sleep_for(std::chrono::milliseconds(1200));
    client_stats = source.stats();
    REQUIRE(client_stats.stored == kShots);
    std::vector<std::string> stored = source.StoredDevicePaths();
    std::sort(stored.begin(), stored.end());
    for (int i = 0; i < kShots; ++i) CHECK(stored[std::size_t(i)] == emulator.DevicePath(i));
  }
  REQUIRE(int(frames.size()) == kShots);
  std::set<std::string> names;
  for (const Frame& frame : frames) names.insert(frame.name);
  CHECK(int(names.size()) == kShots);
  CHECK(NumImageFiles(store) == kShots);
  CHECK(int(JournalLines(store, "stored\t").size()) == kShots);
  for (int i = 0; i < kShots; ++i) {
    const std::filesystem::path stored =
        store / StoreNameForDevicePath(emulator.DevicePath(i));
    CHECK(ReadFileBytes(stored) == ReadFileBytes(images[std::size_t(i)]));
  }
  const CamfiEmulatorStats stats = emulator.stats();
  CHECK(stats.raw_served == kShots);
  const std::vector<std::string> log = emulator.RequestLog();
  CHECK(std::count(log.begin(), log.end(),
                   "GET /raw/%2Fstore_00010001%2FDCIM%2F100CANON%2FIMG_0001.JPG") >= 1);
  CHECK(std::none_of(log.begin(), log.end(), [](const std::string& line) {
    return line.rfind("GET /raw//", 0) == 0;
  }));
  return {stats, client_stats};
}

TEST_CASE("StoreNameForDevicePath keeps folders apart") {
  CHECK(StoreNameForDevicePath("/store_00010001/DCIM/100CANON/IMG_0001.JPG") ==
        "store_00010001_DCIM_100CANON_IMG_0001.JPG");
  CHECK(StoreNameForDevicePath("/store_00010001/DCIM/101CANON/IMG_0001.JPG") !=
        StoreNameForDevicePath("/store_00010001/DCIM/100CANON/IMG_0001.JPG"));
}

TEST_CASE("CamfiOptions::Check rejects a bad port") {
  CamfiOptions options;
  CHECK(options.Check());
  options.event_port = 0;
  CHECK_FALSE(options.Check());
  // Rejected before the store is touched.
  CHECK_THROWS_AS(CamfiSource(options, "/nonexistent/store"),
                  std::invalid_argument);
}

TEST_CASE("camfi: every shot once on a clean link") {
  const Outcome outcome = RunWithFaults({});
  CHECK(outcome.emulator.events_sent >= kShots);
  CHECK(outcome.client.session_failures == 0);
  CHECK(outcome.client.download_failures == 0);
}

TEST_CASE("camfi: socket dropped") {
  const Outcome outcome = RunWithFaults({CamfiFault::kDropSocket});
  CHECK(outcome.emulator.sockets_dropped > 0);
  CHECK(outcome.client.session_failures > 0);
  CHECK(outcome.client.sessions > 1);
}

TEST_CASE("camfi: silent stall") {
  const Outcome outcome = RunWithFaults({CamfiFault::kStall});
  CHECK(outcome.emulator.sockets_stalled > 0);
  // The watchdog, not only the listing, noticed.
  CHECK(outcome.client.session_failures > 0);
  CHECK(outcome.client.sessions > 1);
}

TEST_CASE("camfi: duplicate events") {
  const Outcome outcome = RunWithFaults({CamfiFault::kDuplicate});
  CHECK(outcome.emulator.events_duplicated > 0);
  CHECK(outcome.client.duplicate_events > 0);
}

TEST_CASE("camfi: missing events") {
  const Outcome outcome = RunWithFaults({CamfiFault::kMissing});
  CHECK(outcome.emulator.events_missing > 0);
  CHECK(outcome.client.found_by_listing > 0);
}

TEST_CASE("camfi: out-of-order events") {
  CHECK(RunWithFaults({CamfiFault::kOutOfOrder}).emulator.events_reordered > 0);
}

TEST_CASE("camfi: truncated body") {
  const Outcome outcome = RunWithFaults({CamfiFault::kTruncate});
  CHECK(outcome.emulator.bodies_truncated > 0);
  CHECK(outcome.client.download_failures == outcome.emulator.bodies_truncated);
}

TEST_CASE("camfi: HTTP 500 right after the event") {
  const Outcome outcome = RunWithFaults({CamfiFault::kHttp500});
  CHECK(outcome.emulator.http_500 > 0);
  CHECK(outcome.client.download_failures == outcome.emulator.http_500);
}

TEST_CASE("camfi: authentication required") {
  CHECK(RunWithFaults({CamfiFault::kAuth}, "camfi").emulator.unauthorized > 0);
}

TEST_CASE("camfi: firmware without /info") {
  const Outcome outcome = RunWithFaults({CamfiFault::kLegacyInfo});
  CHECK(outcome.client.session_failures == 0);
}

TEST_CASE("camfi: every fault at once") {
  RunWithFaults({CamfiFault::kDropSocket, CamfiFault::kDuplicate, CamfiFault::kMissing,
                 CamfiFault::kOutOfOrder, CamfiFault::kTruncate, CamfiFault::kHttp500});
}

TEST_CASE("camfi: Engine.IO v4 firmware as an option") {
  const std::filesystem::path dir = testing::MakeTempDir("camfi_eio4");
  CamfiEmulatorOptions emulator_options = FastEmulator(testing::WriteTestJpegs(dir, 3));
  emulator_options.engine_io_version = 4;
  CamfiEmulator emulator(emulator_options);
  CamfiOptions client_options = FastClient(emulator);
  client_options.engine_io_version = 4;
  CamfiSource source(client_options, dir / "store");
  CHECK(testing::PullFrames(&source, [&] { source.Stop(); }, 3, 5).size() == 3);
  // Answering the server's pings keeps the one session alive.
  std::this_thread::sleep_for(std::chrono::milliseconds(800));
  CHECK(source.stats().sessions == 1);
  CHECK(source.stats().session_failures == 0);
}

TEST_CASE("camfi: a wrong password stores nothing and says why") {
  const std::filesystem::path dir = testing::MakeTempDir("camfi_auth");
  CamfiEmulatorOptions emulator_options =
      FastEmulator(testing::WriteTestJpegs(dir, 2));
  emulator_options.faults = {CamfiFault::kAuth};
  CamfiEmulator emulator(emulator_options);
  CamfiOptions client_options = FastClient(emulator);
  client_options.password = "wrong";
  CamfiSource source(client_options, dir / "store");
  std::this_thread::sleep_for(std::chrono::milliseconds(800));
  const CamfiStats stats = source.stats();
  CHECK(stats.sessions == 0);
  CHECK(stats.session_failures > 0);
  CHECK(stats.stored == 0);
}

TEST_CASE("camfi: a new source on the same store replays it and fetches nothing twice") {
  const std::filesystem::path dir = testing::MakeTempDir("camfi_restart");
  const std::vector<std::filesystem::path> images = testing::WriteTestJpegs(dir, 8);
  CamfiEmulatorOptions emulator_options = FastEmulator(images);
  emulator_options.interval_seconds = 0.25;
  CamfiEmulator emulator(emulator_options);
  const std::filesystem::path store = dir / "store";
  std::vector<Frame> first;
  {
    CamfiSource source(FastClient(emulator), store);
    first = testing::PullFrames(&source, [&] { source.Stop(); }, 3, 10);
  }
  REQUIRE(first.size() == 3);
  CamfiSource source(FastClient(emulator), store);
  const std::vector<Frame> second = testing::PullFrames(&source, [&] { source.Stop(); }, 8, 15);
  REQUIRE(second.size() == 8);
  CHECK(source.stats().replayed >= 3);
  for (std::size_t i = 0; i < first.size(); ++i) CHECK(second[i].name == first[i].name);
  std::set<std::string> names;
  for (const Frame& frame : second) names.insert(frame.name);
  CHECK(names.size() == 8);
  std::this_thread::sleep_for(std::chrono::milliseconds(700));
  CHECK(emulator.stats().raw_served == 8);
  CHECK(JournalLines(store, "stored\t").size() == 8);
}

TEST_CASE("camfi: files on the card before a fresh store are ignored unless asked for") {
  const std::filesystem::path dir = testing::MakeTempDir("camfi_existing");
  CamfiEmulatorOptions emulator_options = FastEmulator(testing::WriteTestJpegs(dir, 3));
  CamfiEmulator emulator(emulator_options);
  for (int i = 0; i < 2; ++i) emulator.Shoot();
  {
    CamfiSource source(FastClient(emulator), dir / "ignore");
    // Two shots were on the card before; one more comes after connecting.
    const std::vector<Frame> frames = testing::PullFrames(&source, [&] { source.Stop(); }, 3, 3);
    REQUIRE(frames.size() == 1);
    CHECK(frames[0].name == StoreNameForDevicePath(emulator.DevicePath(2)));
  }
  CamfiOptions fetch_all = FastClient(emulator);
  fetch_all.fetch_existing = true;
  CamfiSource source(fetch_all, dir / "fetch");
  CHECK(testing::PullFrames(&source, [&] { source.Stop(); }, 3, 5).size() == 3);
}

}  // namespace
}  // namespace flysfm
