#pragma once

// The receiving half of RFC 6455 framing, on bytes only (no socket), so that
// it can be tested and fuzzed on its own: frames are cut from the bytes
// received, unmasked, and text/binary fragments joined into messages.
// Everything a peer sends is bounded: a message (its fragments together) over
// `max_message_bytes` is an error as soon as a frame header announces it, so
// memory never grows past about one message; control frames follow the RFC
// (at most 125 bytes, never fragmented).

#include <cstddef>
#include <string>

namespace flysfm {

// An event channel carries packets of a few hundred bytes; 1 MiB leaves room
// for any listing-sized payload a firmware might push.
constexpr std::size_t kDefaultMaxWebSocketMessageBytes = 1u << 20;

class WebSocketReader {
 public:
  enum class Item {
    kNeedMore,  // no complete frame buffered
    kMessage,   // a whole text or binary message
    kPing,      // a ping; its payload is to be echoed in a pong
    kPong,
    kClose,
    kError,  // a protocol violation or a message over the bound
  };

  explicit WebSocketReader(std::size_t max_message_bytes = kDefaultMaxWebSocketMessageBytes)
      : max_message_bytes_(max_message_bytes) {}

  // Bytes as they came off the connection (dropped after an error).
  void Append(const char* data, std::size_t size) {
    if (failure_.empty()) buffer_.append(data, size);
  }
  // The next item the buffered bytes hold, its payload in `*payload`. After
  // kError (`*error` says why) the connection is to be dropped: the reader
  // returns kError from then on.
  Item Next(std::string* payload, std::string* error);

  std::size_t buffered_bytes() const { return buffer_.size() + fragments_.size(); }

 private:
  std::size_t max_message_bytes_;
  std::string buffer_;
  // The fragments of a message not yet complete.
  std::string fragments_;
  bool in_message_ = false;
  std::string failure_;
};

}  // namespace flysfm
