// WebSocket frames as a peer may send them, cut into two reads at a point the
// first byte picks: no input may crash the reader, hand on a message over its
// bound, or keep more than about one message buffered.

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <string>

#include "io/camfi/websocket_reader.h"

namespace {

constexpr std::size_t kMaxMessage = 4096;

// Items until the reader needs more bytes or gives up.
void Drain(flysfm::WebSocketReader* reader) {
  std::string payload;
  std::string error;
  while (true) {
    const flysfm::WebSocketReader::Item item = reader->Next(&payload, &error);
    if (item == flysfm::WebSocketReader::Item::kNeedMore ||
        item == flysfm::WebSocketReader::Item::kError) {
      return;
    }
    if (payload.size() > kMaxMessage) __builtin_trap();
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size == 0) return 0;
  const char* bytes = reinterpret_cast<const char*>(data) + 1;
  const std::size_t length = size - 1;
  const std::size_t split = std::min<std::size_t>(data[0], length);
  flysfm::WebSocketReader reader(kMaxMessage);
  reader.Append(bytes, split);
  Drain(&reader);
  reader.Append(bytes + split, length - split);
  Drain(&reader);
  // Left buffered: at most a message's fragments and one incomplete frame
  // (a data frame within the bound, or a control frame of 125 bytes).
  if (reader.buffered_bytes() > kMaxMessage + 14 + 125) __builtin_trap();
  return 0;
}
