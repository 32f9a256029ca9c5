#pragma once

// The few Engine.IO v3 / Socket.IO (protocol rev 4) packets a CAMFI event
// channel uses (docs/camfi.md 3.2), as text in WebSocket frames:
//   0{"sid":..,"pingInterval":..,"pingTimeout":..}   open (server)
//   2 / 3                                            ping (client) / pong (server);
//                                                    the reverse in Engine.IO v4
//   1                                                close
//   40 / 41                                          namespace connect / disconnect
//   42["file_added","/store_00010001/DCIM/..."]      event

#include <optional>
#include <string>

#include <nlohmann/json.hpp>

namespace flysfm {

// The resource of the direct WebSocket connection (no long-polling first)
// for Engine.IO protocol `version` (3: socket.io 1.x/2.x, what CAMFI runs;
// 4: socket.io 3+, where the server pings and the client sends "40").
std::string EngineIoResource(int version);

struct EngineIoOpen {
  std::string sid;
  int ping_interval_ms = 25000;
  int ping_timeout_ms = 60000;
};

// Bounds of the ping timing an open packet may set (ms): a zero would make
// the watchdog fire at once, and an hour disables it in practice.
constexpr int kMaxEngineIoPingMs = 3600 * 1000;

// nullopt unless `packet` is a well-formed open packet whose JSON nests no
// deeper than `max_json_depth` and whose ping timing is within 1 ms ..
// kMaxEngineIoPingMs.
std::optional<EngineIoOpen> ParseEngineIoOpen(const std::string& packet, int max_json_depth);
std::string FormatEngineIoOpen(const EngineIoOpen& open);

struct SocketIoEvent {
  std::string name;
  nlohmann::json args = nlohmann::json::array();
};

// nullopt unless `packet` is a "42[name, args...]" event on the default
// namespace (a message id between "42" and "[" is accepted and ignored),
// its JSON nested no deeper than `max_json_depth`.
std::optional<SocketIoEvent> ParseSocketIoEvent(const std::string& packet, int max_json_depth);
std::string FormatSocketIoEvent(const std::string& name, const nlohmann::json& args);

}  // namespace flysfm
