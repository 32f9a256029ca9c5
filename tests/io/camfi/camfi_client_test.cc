#include "io/camfi/camfi_client.h"

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <fstream>
#include <set>
#include <sstream>
#include <thread>

#include <catch2/catch.hpp>

#include "io/camfi/camfi_emulator.h"
#include "io/camfi/camfi_journal.h"
#include "io/camfi/engineio_packet.h"
#include "io/sources/image_markers.h"
#include "tests/io/camfi/camfi_fixture.h"
#include "tests/testing/temp_dir.h"

namespace flysfm {
namespace {

constexpr int kShots = 7;

// Shots every 0.1 s, or only by Shoot() with `kByHand`.
constexpr double kByHand = 1000;

CamfiEmulatorOptions FastEmulator(const std::vector<std::filesystem::path>& images,
                                  double interval_seconds = 0.1) {
  CamfiEmulatorOptions options = testing::LoopbackEmulator(images, interval_seconds, 250, 250);
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

// Frames from `source` until `count` or `seconds`.
std::vector<Frame> Pull(CamfiSource* source, int count, double seconds) {
  return testing::PullFrames(
      source, [source] { source->Stop(); }, count, seconds);
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

JournalContents ReadJournal(const std::filesystem::path& store) {
  std::ifstream in(store / "journal.tsv", std::ios::binary);
  std::ostringstream text;
  text << in.rdbuf();
  return ParseJournal(text.str());
}

int NumJournalled(const JournalContents& contents) {
  return int(std::count_if(contents.records.begin(), contents.records.end(),
                           [](const auto& r) { return r.kind == JournalRecord::Kind::kStored; }));
}

// Waits up to `seconds` for `done`; false when it never held.
bool WaitFor(const std::function<bool()>& done, double seconds) {
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::duration<double>(seconds);
  while (!done()) {
    if (std::chrono::steady_clock::now() > deadline) return false;
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  return true;
}

struct Outcome {
  CamfiEmulatorStats emulator;
  CamfiStats client;
};

// Runs a client against an emulator with `faults` until every shot is in
// the store, then checks what every fault must leave intact: each shot
// stored once, byte-identical, downloaded once (besides rechecks), through
// %2F-encoded paths.
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
    frames = Pull(&source, kShots, 15);
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
  // Every download is a shot's first, or a counted recheck of a stored path
  // that an event named again (a late or repeated event).
  CHECK(stats.raw_served == kShots + client_stats.rechecked);
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
  CHECK(Pull(&source, 3, 5).size() == 3);
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
  int first_rechecks = 0;
  {
    CamfiSource source(FastClient(emulator), store);
    first = Pull(&source, 3, 10);
    first_rechecks = source.stats().rechecked;
  }
  REQUIRE(first.size() == 3);
  CamfiSource source(FastClient(emulator), store);
  const std::vector<Frame> second = Pull(&source, 8, 15);
  REQUIRE(second.size() == 8);
  CHECK(source.stats().replayed >= 3);
  for (std::size_t i = 0; i < first.size(); ++i) CHECK(second[i].name == first[i].name);
  std::set<std::string> names;
  for (const Frame& frame : second) names.insert(frame.name);
  CHECK(names.size() == 8);
  std::this_thread::sleep_for(std::chrono::milliseconds(700));
  // An event that comes after a listing fetched its shot is a recheck: the
  // only downloads besides one per shot.
  CHECK(emulator.stats().raw_served == 8 + first_rechecks + source.stats().rechecked);
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
    const std::vector<Frame> frames = Pull(&source, 3, 3);
    REQUIRE(frames.size() == 1);
    CHECK(frames[0].name == StoreNameForDevicePath(emulator.DevicePath(2)));
  }
  CamfiOptions fetch_all = FastClient(emulator);
  fetch_all.fetch_existing = true;
  CamfiSource source(fetch_all, dir / "fetch");
  CHECK(Pull(&source, 3, 5).size() == 3);
}

TEST_CASE("camfi: a full disk rejects the shot, and shots flow again once space is back") {
  for (const bool journal_only : {false, true}) {
    CAPTURE(journal_only);
    const std::filesystem::path dir = testing::MakeTempDir("camfi_full_disk");
    const std::vector<std::filesystem::path> images = testing::WriteTestJpegs(dir, 3);
    CamfiEmulatorOptions emulator_options = FastEmulator(images, kByHand);
    CamfiEmulator emulator(emulator_options);
    CamfiOptions options = FastClient(emulator);
    std::atomic<bool> full{false};
    // ENOSPC for every write, or for the journal's only (the shot's file is
    // then written and must be taken back).
    options.store_write_fault = [&](const std::filesystem::path& file) {
      return full && (!journal_only || file.filename() == "journal.tsv") ? ENOSPC : 0;
    };
    const std::filesystem::path store = dir / "store";
    CamfiSource source(options, store);
    REQUIRE(WaitFor([&] { return source.stats().sessions == 1; }, 5));
    full = true;
    for (int i = 0; i < 3; ++i) emulator.Shoot();
    // Shots arrive, none can be stored; the session goes on.
    REQUIRE(WaitFor([&] { return source.stats().store_failures >= 3; }, 8));
    CHECK(source.stats().stored == 0);
    CHECK(source.stats().session_failures == 0);
    CHECK(NumImageFiles(store) == 0);
    full = false;
    const std::vector<Frame> frames = Pull(&source, 3, 10);
    REQUIRE(frames.size() == 3);
    for (int i = 0; i < 3; ++i) {
      CHECK(ReadFileBytes(store / StoreNameForDevicePath(emulator.DevicePath(i))) ==
            ReadFileBytes(images[std::size_t(i)]));
    }
    CHECK(NumImageFiles(store) == 3);
    const JournalContents journal = ReadJournal(store);
    CHECK(journal.skipped.empty());
    CHECK(journal.complete_bytes == std::filesystem::file_size(store / "journal.tsv"));
    CHECK(NumJournalled(journal) == 3);
    for (const auto& entry : std::filesystem::directory_iterator(store)) {
      CHECK(entry.path().extension() != ".tmp");
    }
  }
}

TEST_CASE("camfi: a swapped card's shots under known paths are new shots") {
  for (const bool announced : {true, false}) {
    CAPTURE(announced);
    const std::filesystem::path dir = testing::MakeTempDir("camfi_swap");
    const std::vector<std::filesystem::path> images = testing::WriteTestJpegs(dir, 4);
    CamfiEmulatorOptions emulator_options = FastEmulator(images, kByHand);
    if (!announced) {
      emulator_options.faults = {CamfiFault::kMissing};
      emulator_options.fault_every = 1;
    }
    CamfiEmulator emulator(emulator_options);
    CamfiOptions options = FastClient(emulator);
    options.reconcile_seconds = 0.2;
    const std::filesystem::path store = dir / "store";
    CamfiSource source(options, store);
    REQUIRE(WaitFor([&] { return source.stats().sessions > 0; }, 5));
    emulator.Shoot();
    emulator.Shoot();
    REQUIRE(Pull(&source, 2, 5).size() == 2);
    emulator.SwapCard();
    // A listing of the empty card.
    std::this_thread::sleep_for(std::chrono::milliseconds(600));
    emulator.Shoot();
    emulator.Shoot();
    const std::vector<Frame> frames = Pull(&source, 2, 5);
    REQUIRE(frames.size() == 2);
    // Same device paths as the first card's shots, new bytes, new names.
    CHECK(frames[0].name == StoreNameForDevicePath(emulator.DevicePath(0), 2));
    CHECK(frames[0].name == "store_00010001_DCIM_100CANON_IMG_0001~2.JPG");
    CHECK(ReadFileBytes(frames[0].path) == ReadFileBytes(images[2]));
    CHECK(ReadFileBytes(frames[1].path) == ReadFileBytes(images[3]));
    CHECK(ReadFileBytes(store / StoreNameForDevicePath(emulator.DevicePath(0))) ==
          ReadFileBytes(images[0]));
    CHECK(source.stats().reused_paths == 2);
    CHECK(NumJournalled(ReadJournal(store)) == 4);
    // The same bytes announced again are a duplicate, not a shot.
    const int duplicates = source.stats().duplicate_events;
    emulator.SendPacket(
        FormatSocketIoEvent("file_added", nlohmann::json::array({emulator.DevicePath(0)})));
    REQUIRE(WaitFor([&] { return source.stats().duplicate_events > duplicates; }, 5));
    CHECK(source.stats().stored == 4);
  }
}

TEST_CASE("camfi: a device that pages by less than asked is listed to the end") {
  const std::filesystem::path dir = testing::MakeTempDir("camfi_paging");
  CamfiEmulatorOptions emulator_options = FastEmulator(testing::WriteTestJpegs(dir, 8));
  emulator_options.files_page_limit = 3;
  CamfiEmulator emulator(emulator_options);
  for (int i = 0; i < 8; ++i) emulator.Shoot();
  CamfiOptions options = FastClient(emulator);
  options.fetch_existing = true;
  CamfiSource source(options, dir / "store");
  CHECK(Pull(&source, 8, 5).size() == 8);
  CHECK(source.stats().found_by_listing == 8);
}

TEST_CASE("camfi: a device that ignores start does not loop the listing") {
  const std::filesystem::path dir = testing::MakeTempDir("camfi_ignore_start");
  CamfiEmulatorOptions emulator_options = FastEmulator(testing::WriteTestJpegs(dir, 4));
  emulator_options.files_ignore_start = true;
  emulator_options.interval_seconds = kByHand;
  CamfiEmulator emulator(emulator_options);
  emulator.Shoot();
  emulator.Shoot();
  CamfiOptions options = FastClient(emulator);
  options.fetch_existing = true;
  options.list_page = 2;  // every page full
  options.reconcile_seconds = 0.2;
  CamfiSource source(options, dir / "store");
  REQUIRE(Pull(&source, 2, 5).size() == 2);
  // Events are still handled: the session is live, not listing.
  emulator.Shoot();
  CHECK(Pull(&source, 1, 5).size() == 1);
  const std::vector<std::string> log = emulator.RequestLog();
  const auto listings = std::count_if(log.begin(), log.end(), [](const std::string& line) {
    return line.rfind("GET /files/", 0) == 0;
  });
  // Two pages a listing, one listing each 0.2 s, for a few seconds at most.
  CHECK(listings < 100);
  CHECK(source.stats().session_failures == 0);
}

TEST_CASE("camfi: a failing listing is counted and retried, the session goes on") {
  const std::vector<std::pair<int, std::string>> failures = {
      {500, R"({"message":"camera busy"})"},
      {200, "<html>busy</html>"},
      {200, R"([1,2,3])"},
      {200, std::string(200, '[') + std::string(200, ']')}};
  for (const auto& [status, body] : failures) {
    CAPTURE(status, body);
    const std::filesystem::path dir = testing::MakeTempDir("camfi_listing_failure");
    CamfiEmulatorOptions emulator_options = FastEmulator(testing::WriteTestJpegs(dir, 2));
    // Shots only the listing can find.
    emulator_options.faults = {CamfiFault::kMissing};
    emulator_options.fault_every = 1;
    emulator_options.files_failures = 3;
    emulator_options.files_failure_status = status;
    emulator_options.files_failure_body = body;
    CamfiEmulator emulator(emulator_options);
    CamfiOptions options = FastClient(emulator);
    options.fetch_existing = true;
    options.reconcile_seconds = 0.2;
    CamfiSource source(options, dir / "store");
    CHECK(Pull(&source, 2, 8).size() == 2);
    CHECK(emulator.stats().files_failed == 3);
    CHECK(source.stats().listing_failures == 3);
    CHECK(source.stats().session_failures == 0);
  }
}

TEST_CASE("camfi: a shot over max_shot_bytes is rejected once, not fetched at every listing") {
  const std::filesystem::path dir = testing::MakeTempDir("camfi_oversized");
  const std::vector<std::filesystem::path> images = testing::WriteTestJpegs(dir, 1);
  CamfiEmulator emulator(FastEmulator(images));
  CamfiOptions options = FastClient(emulator);
  options.max_shot_bytes = std::filesystem::file_size(images[0]) - 1;
  options.reconcile_seconds = 0.2;
  CamfiSource source(options, dir / "store");
  REQUIRE(WaitFor([&] { return source.stats().oversized == 1; }, 5));
  // Several listings later, still one download.
  std::this_thread::sleep_for(std::chrono::milliseconds(800));
  CHECK(source.stats().oversized == 1);
  CHECK(source.stats().stored == 0);
  const std::vector<std::string> log = emulator.RequestLog();
  CHECK(std::count_if(log.begin(), log.end(), [](const std::string& line) {
          return line.rfind("GET /raw/", 0) == 0;
        }) == 1);
}

TEST_CASE("camfi: a trickling download is cut at its total time and fetched again") {
  const std::filesystem::path dir = testing::MakeTempDir("camfi_trickle");
  CamfiEmulatorOptions emulator_options = FastEmulator(testing::WriteTestJpegs(dir, 2));
  emulator_options.faults = {CamfiFault::kTrickle};
  emulator_options.fault_every = 1;
  CamfiEmulator emulator(emulator_options);
  CamfiOptions options = FastClient(emulator);
  // One byte a second never looks idle; only the total bound ends it.
  options.download_idle_seconds = 30;
  options.download_total_seconds = 1;
  CamfiSource source(options, dir / "store");
  CHECK(Pull(&source, 2, 8).size() == 2);
  CHECK(emulator.stats().bodies_trickled == 2);
  CHECK(source.stats().timed_out_downloads == 2);
}

TEST_CASE("camfi: hostile event packets are rejected and counted, shots still flow") {
  const std::filesystem::path dir = testing::MakeTempDir("camfi_hostile_events");
  CamfiEmulatorOptions emulator_options = FastEmulator(testing::WriteTestJpegs(dir, 2), kByHand);
  CamfiEmulator emulator(emulator_options);
  CamfiOptions options = FastClient(emulator);
  options.max_event_message_bytes = 4096;
  CamfiSource source(options, dir / "store");
  REQUIRE(WaitFor([&] { return source.stats().sessions == 1; }, 5));
  emulator.SendPacket("42" + std::string(1000, '[') + std::string(1000, ']'));
  REQUIRE(WaitFor([&] { return source.stats().rejected_packets == 1; }, 5));
  CHECK(source.stats().session_failures == 0);
  // Over the message bound: the channel is dropped and opened again.
  emulator.SendPacket(std::string(8192, 'x'));
  REQUIRE(WaitFor([&] { return source.stats().rejected_packets == 2; }, 5));
  REQUIRE(WaitFor([&] { return source.stats().sessions == 2; }, 5));
  emulator.Shoot();
  emulator.Shoot();
  CHECK(Pull(&source, 2, 5).size() == 2);
}

TEST_CASE("camfi: a restart reads past a torn last record and a malformed one") {
  const std::filesystem::path dir = testing::MakeTempDir("camfi_journal_restart");
  const std::vector<std::filesystem::path> images = testing::WriteTestJpegs(dir, 3);
  CamfiEmulatorOptions emulator_options = FastEmulator(images, kByHand);
  CamfiEmulator emulator(emulator_options);
  const std::filesystem::path store = dir / "store";
  {
    CamfiSource source(FastClient(emulator), store);
    REQUIRE(WaitFor([&] { return source.stats().sessions == 1; }, 5));
    emulator.Shoot();
    REQUIRE(Pull(&source, 1, 5).size() == 1);
  }
  // A record with a bad number, and one a kill -9 cut mid-append.
  std::ofstream(store / "journal.tsv", std::ios::app)
      << "stored\t/x.JPG\tx.JPG\tabc\n"
      << "stored\t/store_00010001/DCIM/100CANON/IMG_0002.JPG\tstore_0";
  CamfiSource source(FastClient(emulator), store);
  CHECK(source.stats().replayed == 1);
  CHECK(source.stats().journal_skipped == 1);
  CHECK(source.stats().journal_torn == 1);
  REQUIRE(WaitFor([&] { return source.stats().sessions == 1; }, 5));
  emulator.Shoot();
  REQUIRE(Pull(&source, 2, 5).size() == 2);
  // The next record starts on a line of its own.
  const JournalContents journal = ReadJournal(store);
  CHECK(journal.skipped.size() == 1);
  CHECK(NumJournalled(journal) == 2);
  CHECK(journal.complete_bytes == std::filesystem::file_size(store / "journal.tsv"));
}

TEST_CASE("StoreNameForDevicePath stays one file inside the store") {
  CHECK(StoreNameForDevicePath("/..") == "_..");
  CHECK(StoreNameForDevicePath("/") == "_");
  CHECK(StoreNameForDevicePath("/a/../../b.JPG") == "a_.._.._b.JPG");
  CHECK(StoreNameForDevicePath("/" + std::string(300, 'a') + ".JPG").size() == 200);
  CHECK(StoreNameForDevicePath("/DCIM/IMG_0001.JPG", 3) == "DCIM_IMG_0001~3.JPG");
}

}  // namespace
}  // namespace flysfm
