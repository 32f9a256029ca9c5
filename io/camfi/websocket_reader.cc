#include "io/camfi/websocket_reader.h"

#include <cstdint>

namespace flysfm {
namespace {

constexpr int kContinuation = 0x0;
constexpr int kText = 0x1;
constexpr int kBinary = 0x2;
constexpr int kClose = 0x8;
constexpr int kPing = 0x9;
constexpr int kPong = 0xA;
constexpr std::size_t kMaxControlPayload = 125;

}  // namespace

WebSocketReader::Item WebSocketReader::Next(std::string* payload, std::string* error) {
  const auto fail = [&](std::string reason) {
    failure_ = std::move(reason);
    *error = failure_;
    buffer_.clear();
    fragments_.clear();
    return Item::kError;
  };
  if (!failure_.empty()) {
    *error = failure_;
    return Item::kError;
  }
  while (true) {
    if (buffer_.size() < 2) return Item::kNeedMore;
    const auto* b = reinterpret_cast<const unsigned char*>(buffer_.data());
    const bool fin = (b[0] & 0x80) != 0;
    const int opcode = b[0] & 0x0F;
    const bool masked = (b[1] & 0x80) != 0;
    std::uint64_t length = b[1] & 0x7F;
    std::size_t header = 2 + (length == 126 ? 2 : length == 127 ? 8 : 0) + (masked ? 4 : 0);
    if ((b[0] & 0x70) != 0) return fail("WebSocket frame with reserved bits set");
    const bool control = (opcode & 0x8) != 0;
    if (opcode != kContinuation && opcode != kText && opcode != kBinary && opcode != kClose &&
        opcode != kPing && opcode != kPong) {
      return fail("WebSocket frame with reserved opcode " + std::to_string(opcode));
    }
    if (control && (!fin || length > kMaxControlPayload)) {
      return fail("WebSocket control frame fragmented or over 125 bytes");
    }
    if (!control && (opcode == kContinuation) != in_message_) {
      return fail(in_message_ ? "WebSocket message interrupted by a new one"
                              : "WebSocket continuation frame without a message");
    }
    if (buffer_.size() < header) return Item::kNeedMore;
    if (length == 126) length = (std::uint64_t(b[2]) << 8) | b[3];
    if (length == 127) {
      length = 0;
      for (int i = 0; i < 8; ++i) length = (length << 8) | b[2 + i];
    }
    // Checked on the header, before any of the payload is buffered.
    if (!control && length > max_message_bytes_ - fragments_.size()) {
      return fail("WebSocket message over " + std::to_string(max_message_bytes_) + " bytes");
    }
    if (buffer_.size() - header < length) return Item::kNeedMore;
    std::string data = buffer_.substr(header, std::size_t(length));
    if (masked) {
      const unsigned char* key = b + header - 4;
      for (std::size_t i = 0; i < data.size(); ++i) data[i] = char(data[i] ^ key[i % 4]);
    }
    buffer_.erase(0, header + std::size_t(length));
    if (control) {
      *payload = std::move(data);
      return opcode == kClose ? Item::kClose : opcode == kPing ? Item::kPing : Item::kPong;
    }
    fragments_ += data;
    in_message_ = !fin;
    if (fin) {
      *payload = std::move(fragments_);
      fragments_.clear();
      return Item::kMessage;
    }
  }
}

}  // namespace flysfm
