// Engine.IO / Socket.IO packets as an event channel may deliver them: no input
// may crash the parsers, and what they accept must survive formatting and
// parsing again unchanged.

#include <cstddef>
#include <cstdint>
#include <string>

#include "io/camfi/bounded_json.h"
#include "io/camfi/engineio_packet.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string packet(reinterpret_cast<const char*>(data), size);
  constexpr int kDepth = flysfm::kDefaultMaxJsonDepth;
  if (const auto open = flysfm::ParseEngineIoOpen(packet, kDepth)) {
    const auto again = flysfm::ParseEngineIoOpen(flysfm::FormatEngineIoOpen(*open), kDepth);
    if (!again || again->sid != open->sid || again->ping_interval_ms != open->ping_interval_ms ||
        again->ping_timeout_ms != open->ping_timeout_ms) {
      __builtin_trap();
    }
  }
  if (const auto event = flysfm::ParseSocketIoEvent(packet, kDepth)) {
    const auto again =
        flysfm::ParseSocketIoEvent(flysfm::FormatSocketIoEvent(event->name, event->args), kDepth);
    if (!again || again->name != event->name || again->args != event->args) __builtin_trap();
  }
  return 0;
}
