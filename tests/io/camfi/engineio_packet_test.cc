#include "io/camfi/engineio_packet.h"

#include <catch2/catch.hpp>

#include "io/camfi/bounded_json.h"

namespace flysfm {
namespace {

TEST_CASE("ParseEngineIoOpen reads the ping timing") {
  const auto open =
      ParseEngineIoOpen(R"(0{"sid":"abc","upgrades":[],"pingInterval":25000,"pingTimeout":60000})",
                        kDefaultMaxJsonDepth);
  REQUIRE(open);
  CHECK(open->sid == "abc");
  CHECK(open->ping_interval_ms == 25000);
  CHECK(open->ping_timeout_ms == 60000);
  const auto round_trip =
      ParseEngineIoOpen(FormatEngineIoOpen({"x", 300, 400}), kDefaultMaxJsonDepth);
  REQUIRE(round_trip);
  CHECK(round_trip->ping_interval_ms == 300);
  CHECK(round_trip->ping_timeout_ms == 400);
}

TEST_CASE("ParseEngineIoOpen rejects other packets") {
  CHECK_FALSE(ParseEngineIoOpen("40", kDefaultMaxJsonDepth));
  CHECK_FALSE(ParseEngineIoOpen("0{not json", kDefaultMaxJsonDepth));
  CHECK_FALSE(ParseEngineIoOpen(R"(0{"pingInterval":0})", kDefaultMaxJsonDepth));
  CHECK_FALSE(ParseEngineIoOpen("", kDefaultMaxJsonDepth));
}

TEST_CASE("ParseSocketIoEvent reads file_added") {
  const auto event = ParseSocketIoEvent(
      R"(42["file_added","/store_00010001/DCIM/100CANON/IMG_0001.JPG"])", kDefaultMaxJsonDepth);
  REQUIRE(event);
  CHECK(event->name == "file_added");
  REQUIRE(event->args.size() == 1);
  CHECK(event->args[0] == "/store_00010001/DCIM/100CANON/IMG_0001.JPG");
  // With a message id.
  const auto with_id =
      ParseSocketIoEvent(R"(4212["camera_add",{"model":"x"}])", kDefaultMaxJsonDepth);
  REQUIRE(with_id);
  CHECK(with_id->name == "camera_add");
  const auto round_trip = ParseSocketIoEvent(
      FormatSocketIoEvent("file_added", nlohmann::json::array({"/a.JPG"})), kDefaultMaxJsonDepth);
  REQUIRE(round_trip);
  CHECK(round_trip->args[0] == "/a.JPG");
}

TEST_CASE("ParseSocketIoEvent rejects other packets") {
  CHECK_FALSE(ParseSocketIoEvent("3", kDefaultMaxJsonDepth));
  CHECK_FALSE(ParseSocketIoEvent("40", kDefaultMaxJsonDepth));
  CHECK_FALSE(ParseSocketIoEvent("42[]", kDefaultMaxJsonDepth));
  CHECK_FALSE(ParseSocketIoEvent("42[1,2]", kDefaultMaxJsonDepth));
  CHECK_FALSE(ParseSocketIoEvent("42[\"file_added\"", kDefaultMaxJsonDepth));
}

TEST_CASE("Engine.IO and Socket.IO parsers refuse deep nesting and absurd timing") {
  const std::string deep = std::string(100000, '[') + std::string(100000, ']');
  CHECK_FALSE(ParseSocketIoEvent("42" + deep, kDefaultMaxJsonDepth));
  CHECK_FALSE(ParseEngineIoOpen("0{\"sid\":" + deep + "}", kDefaultMaxJsonDepth));
  // Within the bound it parses: depth 3 here.
  CHECK(ParseSocketIoEvent(R"(42["camera_add",{"a":[1]}])", 3));
  CHECK_FALSE(ParseSocketIoEvent(R"(42["camera_add",{"a":[1]}])", 2));
  // A double far outside int must not be converted to one.
  CHECK_FALSE(ParseEngineIoOpen(R"(0{"pingInterval":1e300})", kDefaultMaxJsonDepth));
  CHECK_FALSE(ParseEngineIoOpen(R"(0{"pingTimeout":-5})", kDefaultMaxJsonDepth));
}

}  // namespace
}  // namespace flysfm
