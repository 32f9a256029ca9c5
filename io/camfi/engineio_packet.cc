#include "io/camfi/engineio_packet.h"

#include <cctype>

#include "io/camfi/bounded_json.h"

namespace flysfm {

std::string EngineIoResource(int version) {
  return "/socket.io/?EIO=" + std::to_string(version) + "&transport=websocket";
}

namespace {

// `body[key]` when it is a number in 1 .. kMaxEngineIoPingMs; `fallback`
// when absent; nullopt for anything else (converting a huge double to int
// would be undefined).
std::optional<int> PingMs(const nlohmann::json& body, const char* key, int fallback) {
  const auto found = body.find(key);
  if (found == body.end()) return fallback;
  if (!found->is_number()) return std::nullopt;
  const double ms = found->get<double>();
  if (!(ms >= 1 && ms <= kMaxEngineIoPingMs)) return std::nullopt;
  return int(ms);
}

}  // namespace

std::optional<EngineIoOpen> ParseEngineIoOpen(const std::string& packet, int max_json_depth) {
  if (packet.empty() || packet[0] != '0') return std::nullopt;
  std::string problem;
  const std::optional<nlohmann::json> body =
      ParseBoundedJson(std::string_view(packet).substr(1), max_json_depth, &problem);
  if (!body || !body->is_object()) return std::nullopt;
  EngineIoOpen open;
  const auto sid = body->find("sid");
  if (sid != body->end() && sid->is_string()) open.sid = sid->get<std::string>();
  const std::optional<int> interval = PingMs(*body, "pingInterval", open.ping_interval_ms);
  const std::optional<int> timeout = PingMs(*body, "pingTimeout", open.ping_timeout_ms);
  if (!interval || !timeout) return std::nullopt;
  open.ping_interval_ms = *interval;
  open.ping_timeout_ms = *timeout;
  return open;
}

std::string FormatEngineIoOpen(const EngineIoOpen& open) {
  const nlohmann::json body = {{"sid", open.sid},
                               {"upgrades", nlohmann::json::array()},
                               {"pingInterval", open.ping_interval_ms},
                               {"pingTimeout", open.ping_timeout_ms}};
  return "0" + body.dump();
}

std::optional<SocketIoEvent> ParseSocketIoEvent(const std::string& packet, int max_json_depth) {
  if (packet.compare(0, 2, "42") != 0) return std::nullopt;
  std::size_t start = 2;
  while (start < packet.size() && std::isdigit(static_cast<unsigned char>(packet[start]))) {
    ++start;
  }
  std::string problem;
  std::optional<nlohmann::json> body =
      ParseBoundedJson(std::string_view(packet).substr(start), max_json_depth, &problem);
  if (!body || !body->is_array() || body->empty() || !(*body)[0].is_string()) {
    return std::nullopt;
  }
  SocketIoEvent event;
  event.name = (*body)[0].get<std::string>();
  for (std::size_t i = 1; i < body->size(); ++i) event.args.push_back(std::move((*body)[i]));
  return event;
}

std::string FormatSocketIoEvent(const std::string& name, const nlohmann::json& args) {
  nlohmann::json body = nlohmann::json::array({name});
  for (const nlohmann::json& arg : args) body.push_back(arg);
  return "42" + body.dump();
}

}  // namespace flysfm
