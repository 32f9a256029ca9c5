#include "io/camfi/engineio_packet.h"

#include <cctype>

namespace flysfm {

std::string EngineIoResource(int version) {
  return "/socket.io/?EIO=" + std::to_string(version) + "&transport=websocket";
}

std::optional<EngineIoOpen> ParseEngineIoOpen(const std::string& packet) {
  if (packet.empty() || packet[0] != '0') return std::nullopt;
  const nlohmann::json body = nlohmann::json::parse(packet.substr(1), nullptr, false);
  if (!body.is_object()) return std::nullopt;
  EngineIoOpen open;
  if (body.contains("sid") && body["sid"].is_string()) open.sid = body["sid"];
  if (body.contains("pingInterval") && body["pingInterval"].is_number()) {
    open.ping_interval_ms = body["pingInterval"];
  }
  if (body.contains("pingTimeout") && body["pingTimeout"].is_number()) {
    open.ping_timeout_ms = body["pingTimeout"];
  }
  if (open.ping_interval_ms <= 0 || open.ping_timeout_ms <= 0) return std::nullopt;
  return open;
}

std::string FormatEngineIoOpen(const EngineIoOpen& open) {
  const nlohmann::json body = {{"sid", open.sid},
                               {"upgrades", nlohmann::json::array()},
                               {"pingInterval", open.ping_interval_ms},
                               {"pingTimeout", open.ping_timeout_ms}};
  return "0" + body.dump();
}

std::optional<SocketIoEvent> ParseSocketIoEvent(const std::string& packet) {
  if (packet.compare(0, 2, "42") != 0) return std::nullopt;
  std::size_t start = 2;
  while (start < packet.size() && std::isdigit(static_cast<unsigned char>(packet[start]))) {
    ++start;
  }
  const nlohmann::json body = nlohmann::json::parse(packet.substr(start), nullptr, false);
  if (!body.is_array() || body.empty() || !body[0].is_string()) return std::nullopt;
  SocketIoEvent event;
  event.name = body[0];
  for (std::size_t i = 1; i < body.size(); ++i) event.args.push_back(body[i]);
  return event;
}

std::string FormatSocketIoEvent(const std::string& name, const nlohmann::json& args) {
  nlohmann::json body = nlohmann::json::array({name});
  for (const nlohmann::json& arg : args) body.push_back(arg);
  return "42" + body.dump();
}

}  // namespace flysfm
