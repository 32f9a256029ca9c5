#include "io/camfi/camfi_emulator.h"

#include <nlohmann/json.hpp>

#include <catch2/catch.hpp>

#include "io/camfi/camfi_http.h"
#include "io/camfi/bounded_json.h"
#include "io/camfi/engineio_packet.h"
#include "io/camfi/websocket.h"
#include "io/sources/image_markers.h"
#include "tests/io/camfi/camfi_fixture.h"
#include "tests/testing/temp_dir.h"

namespace flysfm {
namespace {

CamfiEmulatorOptions Options(const std::filesystem::path& dir, int shots) {
  return testing::LoopbackEmulator(testing::WriteTestJpegs(dir, shots), 0.1, 300, 400);
}

TEST_CASE("Fault names round-trip") {
  for (const std::string& name : CamfiFaultNames()) {
    const std::optional<CamfiFault> fault = ParseCamfiFault(name);
    REQUIRE(fault);
    CHECK(CamfiFaultName(*fault) == name);
  }
  CHECK_FALSE(ParseCamfiFault("nonsense"));
}

TEST_CASE("CamfiEmulatorOptions::Check") {
  CamfiEmulatorOptions options;
  CHECK_FALSE(options.Check());  // no images
  options.images = {"a.jpg"};
  CHECK(options.Check());
  options.fault_every = 0;
  CHECK_FALSE(options.Check());
}

TEST_CASE("The emulator serves the card under camera-style paths") {
  const std::filesystem::path dir = testing::MakeTempDir("camfi_emulator");
  const CamfiEmulatorOptions options = Options(dir, 3);
  CamfiEmulator emulator(options);
  CHECK(emulator.DevicePath(0) == "/store_00010001/DCIM/100CANON/IMG_0001.JPG");
  const CamfiHttp http("127.0.0.1", emulator.http_port(), "");
  const HttpResult info = http.Get("/info", testing::kQuickCall);
  CHECK(info.status == 200);
  CHECK(nlohmann::json::parse(info.BodyText()).contains("version"));
  CHECK(nlohmann::json::parse(http.Get("/camera", testing::kQuickCall).BodyText())["model"] != "");
  CHECK(http.Get("/files/0/100", testing::kQuickCall).BodyText() == "[]");
  emulator.Shoot();
  emulator.Shoot();
  const nlohmann::json files =
      nlohmann::json::parse(http.Get("/files/0/100", testing::kQuickCall).BodyText());
  REQUIRE(files.size() == 2);
  CHECK(files[1] == emulator.DevicePath(1));
  CHECK(nlohmann::json::parse(http.Get("/files/1/100", testing::kQuickCall).BodyText()).size() ==
        1);
  // The path must come as one %2F-encoded segment.
  const HttpResult raw =
      http.Get("/raw/" + EncodeDevicePath(emulator.DevicePath(1)), testing::kQuickCall);
  CHECK(raw.status == 200);
  CHECK(raw.body == ReadFileBytes(options.images[1]));
  CHECK(http.Get("/raw/" + emulator.DevicePath(1), testing::kQuickCall).status == 500);
  // Not yet shot.
  CHECK(http.Get("/raw/" + EncodeDevicePath(emulator.DevicePath(2)), testing::kQuickCall).status ==
        500);
}

TEST_CASE("The emulator's event channel speaks Engine.IO v3") {
  const std::filesystem::path dir = testing::MakeTempDir("camfi_emulator_events");
  CamfiEmulatorOptions options = Options(dir, 2);
  // No interval shot during the test.
  options.interval_seconds = 60;
  CamfiEmulator emulator(options);
  WebSocket socket =
      WebSocket::Connect("127.0.0.1", emulator.event_port(), EngineIoResource(3), 2000);
  std::string packet;
  REQUIRE(socket.Receive(&packet, 2000) == WebSocket::Status::kMessage);
  const std::optional<EngineIoOpen> open = ParseEngineIoOpen(packet, kDefaultMaxJsonDepth);
  REQUIRE(open);
  CHECK(open->ping_interval_ms == 300);
  CHECK(open->ping_timeout_ms == 400);
  REQUIRE(socket.Receive(&packet, 2000) == WebSocket::Status::kMessage);
  CHECK(packet == "40");
  socket.Send("2");
  REQUIRE(socket.Receive(&packet, 2000) == WebSocket::Status::kMessage);
  CHECK(packet == "3");
  // A remote trigger (/takepic/true) is announced.
  emulator.Shoot();
  REQUIRE(socket.Receive(&packet, 2000) == WebSocket::Status::kMessage);
  const std::optional<SocketIoEvent> event = ParseSocketIoEvent(packet, kDefaultMaxJsonDepth);
  REQUIRE(event);
  CHECK(event->name == "file_added");
  CHECK(event->args[0] == emulator.DevicePath(0));
}

TEST_CASE("The emulator's auth and legacy firmware faults") {
  const std::filesystem::path dir = testing::MakeTempDir("camfi_emulator_auth");
  CamfiEmulatorOptions options = Options(dir, 1);
  options.faults = {CamfiFault::kAuth, CamfiFault::kLegacyInfo};
  options.password = "secret";
  CamfiEmulator emulator(options);
  CHECK(
      CamfiHttp("127.0.0.1", emulator.http_port(), "").Get("/camera", testing::kQuickCall).status ==
      401);
  CHECK(CamfiHttp("127.0.0.1", emulator.http_port(), "nope")
            .Get("/camera", testing::kQuickCall)
            .status == 401);
  const CamfiHttp http("127.0.0.1", emulator.http_port(), "secret");
  CHECK(http.Get("/camera", testing::kQuickCall).status == 200);
  CHECK(http.Get("/info", testing::kQuickCall).status == 404);
  CHECK(emulator.stats().unauthorized >= 2);
}

TEST_CASE("A per-shot fault hits every fault_every-th shot") {
  const std::filesystem::path dir = testing::MakeTempDir("camfi_emulator_seed");
  CamfiEmulatorOptions options = Options(dir, 6);
  options.faults = {CamfiFault::kMissing};
  options.seed = 7;
  std::vector<int> missing;
  for (int run = 0; run < 2; ++run) {
    CamfiEmulator emulator(options);
    for (int i = 0; i < 6; ++i) emulator.Shoot();
    missing.push_back(emulator.stats().events_missing);
  }
  CHECK(missing[0] == 2);
  CHECK(missing[1] == missing[0]);
}

TEST_CASE("The emulator's Engine.IO v4 mode: the server pings and the client joins") {
  const std::filesystem::path dir = testing::MakeTempDir("camfi_emulator_eio4");
  CamfiEmulatorOptions options = Options(dir, 1);
  options.engine_io_version = 4;
  options.interval_seconds = 60;
  CamfiEmulator emulator(options);
  std::string packet;
  // A v3 client is turned away.
  WebSocket v3 = WebSocket::Connect("127.0.0.1", emulator.event_port(), EngineIoResource(3), 2000);
  CHECK(v3.Receive(&packet, 2000) == WebSocket::Status::kClosed);
  WebSocket socket =
      WebSocket::Connect("127.0.0.1", emulator.event_port(), EngineIoResource(4), 2000);
  REQUIRE(socket.Receive(&packet, 2000) == WebSocket::Status::kMessage);
  REQUIRE(ParseEngineIoOpen(packet, kDefaultMaxJsonDepth));
  socket.Send("40");
  REQUIRE(socket.Receive(&packet, 2000) == WebSocket::Status::kMessage);
  CHECK(packet.rfind("40{", 0) == 0);
  REQUIRE(socket.Receive(&packet, 2000) == WebSocket::Status::kMessage);
  CHECK(packet == "2");
}

}  // namespace
}  // namespace flysfm
