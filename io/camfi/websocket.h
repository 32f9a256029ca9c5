#pragma once

// A minimal RFC 6455 WebSocket over a blocking TCP socket, both ends: enough
// for the Engine.IO v3 event channel of a CAMFI transmitter (text frames,
// ping/pong/close control frames) and for the emulator that stands in for it.
// Every read takes a timeout, so a silent peer never blocks a caller forever.
// websocketpp's own client/server needs an asio event loop per endpoint; the
// handshake's SHA-1 and base64 are taken from its header-only helpers.

#include <optional>
#include <string>

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
  // (refused, timed out, not a WebSocket answer).
  static WebSocket Connect(const std::string& host, int port,
                           const std::string& resource, int timeout_ms);
  // Server side, on an accepted TCP connection (takes ownership of `fd`):
  // reads the upgrade request, answers 101 and returns the socket with the
  // request's target; nullopt (connection closed) for anything else.
  static std::optional<WebSocket> Accept(int fd, int timeout_ms, std::string* target);

  // One text message. False when the connection is gone.
  bool Send(const std::string& text);
  // Waits up to `timeout_ms` for one complete text or binary message,
  // answering pings on the way.
  Status Receive(std::string* message, int timeout_ms);
  // Closes the TCP connection without a closing handshake (what a dropped
  // link looks like to the peer).
  void Close();
  bool is_open() const { return fd_ >= 0; }

 private:
  WebSocket(int fd, bool mask) : fd_(fd), mask_(mask) {}
  bool SendFrame(int opcode, const std::string& payload);
  // Appends what arrives within `timeout_ms`; false on close or error.
  bool Fill(int timeout_ms, bool* timed_out);

  int fd_ = -1;
  // Clients mask their frames, servers do not (RFC 6455 5.3).
  bool mask_ = false;
  std::string buffer_;
  std::string fragments_;
};

// The Sec-WebSocket-Accept value for a Sec-WebSocket-Key.
std::string WebSocketAcceptKey(const std::string& key);

}  // namespace flysfm
