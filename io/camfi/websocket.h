#pragma once

// A minimal RFC 6455 WebSocket over a blocking TCP socket, both ends: enough
// for the Engine.IO v3 event channel of a CAMFI transmitter (text frames,
// ping/pong/close control frames) and for the emulator that stands in for it.
// Every read takes a timeout, so a silent peer never blocks a caller forever.
// websocketpp's own client/server needs an asio event loop per endpoint; the
// handshake's SHA-1 and base64 are taken from its header-only helpers.

#include <cstddef>
#include <optional>
#include <string>

#include "io/camfi/websocket_reader.h"

namespace flysfm {

class WebSocket {
 public:
  enum class Status { kMessage, kTimeout, kClosed };

  WebSocket() = default;
  WebSocket(WebSocket&& other) noexcept;
  WebSocket& operator=(WebSocket&& other) noexcept;
  WebSocket(const WebSocket&) = delete;
  WebSocket& operator=(const WebSocket&) = delete;
  ~WebSocket();

  // Client side: TCP connect to host:port, GET `resource` with an Upgrade,
  // check the server's accept key. Throws std::runtime_error with the reason
  // (refused, timed out, not a WebSocket answer). A message received over
  // `max_message_bytes` closes the connection (see error()).
  static WebSocket Connect(const std::string& host, int port, const std::string& resource,
                           int timeout_ms,
                           std::size_t max_message_bytes = kDefaultMaxWebSocketMessageBytes);
  // Server side, on an accepted TCP connection (takes ownership of `fd`):
  // reads the upgrade request, answers 101 and returns the socket with the
  // request's target; nullopt (connection closed) for anything else.
  static std::optional<WebSocket> Accept(
      int fd, int timeout_ms, std::string* target,
      std::size_t max_message_bytes = kDefaultMaxWebSocketMessageBytes);

  // One text message. False when the connection is gone.
  bool Send(const std::string& text);
  // Waits up to `timeout_ms` for one complete text or binary message,
  // answering pings on the way (a peer sending only pings still returns
  // kTimeout on time). kClosed after a protocol violation or an oversized
  // message too, with error() saying which.
  Status Receive(std::string* message, int timeout_ms);
  // Why the connection was dropped on our side; empty for a peer's close.
  const std::string& error() const { return error_; }
  // Closes the TCP connection without a closing handshake (what a dropped
  // link looks like to the peer).
  void Close();
  bool is_open() const { return fd_ >= 0; }

 private:
  WebSocket(int fd, bool mask, std::size_t max_message_bytes)
      : fd_(fd), mask_(mask), reader_(max_message_bytes) {}
  bool SendFrame(int opcode, const std::string& payload);
  // Hands what arrives within `timeout_ms` to the reader; false on close or
  // error.
  bool Fill(int timeout_ms, bool* timed_out);

  int fd_ = -1;
  // Clients mask their frames, servers do not (RFC 6455 5.3).
  bool mask_ = false;
  WebSocketReader reader_;
  std::string error_;
};

// The Sec-WebSocket-Accept value for a Sec-WebSocket-Key.
std::string WebSocketAcceptKey(const std::string& key);

}  // namespace flysfm
