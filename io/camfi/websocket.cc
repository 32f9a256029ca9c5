#include "io/camfi/websocket.h"

#include <netdb.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <poll.h>
#include <sys/ioctl.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cstring>
#include <random>
#include <stdexcept>

#include <websocketpp/base64/base64.hpp>
#include <websocketpp/sha1/sha1.hpp>

namespace flysfm {
namespace {

using Clock = std::chrono::steady_clock;

constexpr int kText = 0x1;
constexpr int kClose = 0x8;
constexpr int kPong = 0xA;

int RemainingMs(Clock::time_point deadline) {
  const auto left =
      std::chrono::duration_cast<std::chrono::milliseconds>(deadline - Clock::now());
  return left.count() > 0 ? int(left.count()) : 0;
}

bool SendAll(int fd, const char* data, std::size_t size) {
  while (size > 0) {
    const ssize_t sent = ::send(fd, data, size, MSG_NOSIGNAL);
    if (sent < 0 && errno == EINTR) continue;
    if (sent <= 0) return false;
    data += sent;
    size -= std::size_t(sent);
  }
  return true;
}

// Reads until the blank line that ends an HTTP head; the head (and nothing
// after it) is returned, bytes past it stay in `rest`.
bool ReadHttpHead(int fd, int timeout_ms, std::string* head, std::string* rest) {
  const Clock::time_point deadline = Clock::now() + std::chrono::milliseconds(timeout_ms);
  std::string data;
  char chunk[1024];
  while (true) {
    const std::size_t end = data.find("\r\n\r\n");
    if (end != std::string::npos) {
      *head = data.substr(0, end + 4);
      *rest = data.substr(end + 4);
      return true;
    }
    if (data.size() > 16384) return false;
    pollfd p{fd, POLLIN, 0};
    const int ready = ::poll(&p, 1, RemainingMs(deadline));
    if (ready < 0 && errno == EINTR) continue;
    if (ready <= 0) return false;
    const ssize_t n = ::recv(fd, chunk, sizeof(chunk), 0);
    if (n <= 0) return false;
    data.append(chunk, std::size_t(n));
  }
}

std::string HeaderValue(const std::string& head, const std::string& name) {
  std::size_t pos = 0;
  while ((pos = head.find("\r\n", pos)) != std::string::npos) {
    pos += 2;
    const std::size_t colon = head.find(':', pos);
    const std::size_t eol = head.find("\r\n", pos);
    if (colon == std::string::npos || eol == std::string::npos || colon > eol) continue;
    if (strncasecmp(head.c_str() + pos, name.c_str(), name.size()) == 0 &&
        colon - pos == name.size()) {
      std::size_t begin = colon + 1;
      while (begin < eol && head[begin] == ' ') ++begin;
      return head.substr(begin, eol - begin);
    }
  }
  return "";
}

int ConnectTcp(const std::string& host, int port, int timeout_ms) {
  addrinfo hints{};
  hints.ai_family = AF_UNSPEC;
  hints.ai_socktype = SOCK_STREAM;
  addrinfo* found = nullptr;
  const int error = ::getaddrinfo(host.c_str(), std::to_string(port).c_str(), &hints, &found);
  if (error != 0) {
    throw std::runtime_error("cannot resolve " + host + ": " + gai_strerror(error));
  }
  std::string reason = "no address";
  for (addrinfo* a = found; a != nullptr; a = a->ai_next) {
    const int fd = ::socket(a->ai_family, a->ai_socktype | SOCK_NONBLOCK, a->ai_protocol);
    if (fd < 0) continue;
    int result = ::connect(fd, a->ai_addr, a->ai_addrlen);
    if (result < 0 && errno == EINPROGRESS) {
      pollfd p{fd, POLLOUT, 0};
      result = ::poll(&p, 1, timeout_ms);
      if (result == 0) {
        reason = "timed out";
        result = -1;
      } else if (result > 0) {
        int so_error = 0;
        socklen_t len = sizeof(so_error);
        ::getsockopt(fd, SOL_SOCKET, SO_ERROR, &so_error, &len);
        result = so_error == 0 ? 0 : -1;
        if (so_error != 0) reason = std::strerror(so_error);
      }
    } else if (result < 0) {
      reason = std::strerror(errno);
    }
    if (result == 0) {
      ::freeaddrinfo(found);
      // Back to blocking: every later read and write goes through poll().
      const int flags = 1;
      ::setsockopt(fd, IPPROTO_TCP, TCP_NODELAY, &flags, sizeof(flags));
      int mode = 0;
      ::ioctl(fd, FIONBIO, &mode);
      return fd;
    }
    ::close(fd);
  }
  ::freeaddrinfo(found);
  throw std::runtime_error("cannot connect to " + host + ":" + std::to_string(port) +
                           ": " + reason);
}

}  // namespace

std::string WebSocketAcceptKey(const std::string& key) {
  const std::string input = key + "258EAFA5-E914-47DA-95CA-C5AB0DC85B11";
  unsigned char hash[20];
  websocketpp::sha1::calc(input.data(), input.size(), hash);
  return websocketpp::base64_encode(hash, sizeof(hash));
}

WebSocket::WebSocket(WebSocket&& other) noexcept
    : fd_(other.fd_),
      mask_(other.mask_),
      reader_(std::move(other.reader_)),
      error_(std::move(other.error_)) {
  other.fd_ = -1;
}

WebSocket& WebSocket::operator=(WebSocket&& other) noexcept {
  if (this != &other) {
    Close();
    fd_ = other.fd_;
    mask_ = other.mask_;
    reader_ = std::move(other.reader_);
    error_ = std::move(other.error_);
    other.fd_ = -1;
  }
  return *this;
}

WebSocket::~WebSocket() { Close(); }

void WebSocket::Close() {
  if (fd_ >= 0) {
    ::shutdown(fd_, SHUT_RDWR);
    ::close(fd_);
    fd_ = -1;
  }
}

WebSocket WebSocket::Connect(const std::string& host, int port, const std::string& resource,
                             int timeout_ms, std::size_t max_message_bytes) {
  WebSocket socket(ConnectTcp(host, port, timeout_ms), /*mask=*/true, max_message_bytes);
  std::random_device random;
  unsigned char nonce[16];
  for (unsigned char& byte : nonce) byte = static_cast<unsigned char>(random());
  const std::string key = websocketpp::base64_encode(nonce, sizeof(nonce));
  const std::string request = "GET " + resource + " HTTP/1.1\r\nHost: " + host + ":" +
                              std::to_string(port) +
                              "\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n"
                              "Sec-WebSocket-Key: " +
                              key + "\r\nSec-WebSocket-Version: 13\r\n\r\n";
  if (!SendAll(socket.fd_, request.data(), request.size())) {
    throw std::runtime_error("connection closed while sending the upgrade request");
  }
  std::string head;
  std::string rest;
  if (!ReadHttpHead(socket.fd_, timeout_ms, &head, &rest)) {
    throw std::runtime_error("no answer to the WebSocket upgrade request");
  }
  socket.reader_.Append(rest.data(), rest.size());
  if (head.compare(0, 12, "HTTP/1.1 101") != 0) {
    throw std::runtime_error("WebSocket upgrade refused: " + head.substr(0, head.find('\r')));
  }
  if (HeaderValue(head, "Sec-WebSocket-Accept") != WebSocketAcceptKey(key)) {
    throw std::runtime_error("WebSocket upgrade answered with a wrong accept key");
  }
  return socket;
}

std::optional<WebSocket> WebSocket::Accept(int fd, int timeout_ms, std::string* target,
                                           std::size_t max_message_bytes) {
  WebSocket socket(fd, /*mask=*/false, max_message_bytes);
  std::string head;
  std::string rest;
  if (!ReadHttpHead(fd, timeout_ms, &head, &rest)) return std::nullopt;
  socket.reader_.Append(rest.data(), rest.size());
  const std::size_t space1 = head.find(' ');
  const std::size_t space2 = head.find(' ', space1 + 1);
  const std::string key = HeaderValue(head, "Sec-WebSocket-Key");
  if (head.compare(0, 4, "GET ") != 0 || space2 == std::string::npos || key.empty()) {
    const std::string answer = "HTTP/1.1 400 Bad Request\r\nContent-Length: 0\r\n\r\n";
    SendAll(fd, answer.data(), answer.size());
    return std::nullopt;
  }
  *target = head.substr(space1 + 1, space2 - space1 - 1);
  const std::string answer =
      "HTTP/1.1 101 Switching Protocols\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n"
      "Sec-WebSocket-Accept: " +
      WebSocketAcceptKey(key) + "\r\n\r\n";
  if (!SendAll(fd, answer.data(), answer.size())) return std::nullopt;
  return socket;
}

bool WebSocket::Send(const std::string& text) { return SendFrame(kText, text); }

bool WebSocket::SendFrame(int opcode, const std::string& payload) {
  if (fd_ < 0) return false;
  std::string frame;
  frame.push_back(char(0x80 | opcode));
  const char mask_bit = mask_ ? char(0x80) : char(0);
  if (payload.size() < 126) {
    frame.push_back(char(mask_bit | char(payload.size())));
  } else if (payload.size() <= 0xFFFF) {
    frame.push_back(char(mask_bit | 126));
    frame.push_back(char(payload.size() >> 8));
    frame.push_back(char(payload.size() & 0xFF));
  } else {
    frame.push_back(char(mask_bit | 127));
    for (int shift = 56; shift >= 0; shift -= 8) {
      frame.push_back(char((std::uint64_t(payload.size()) >> shift) & 0xFF));
    }
  }
  if (mask_) {
    static thread_local std::mt19937 random(std::random_device{}());
    unsigned char key[4];
    for (unsigned char& byte : key) byte = static_cast<unsigned char>(random());
    frame.append(reinterpret_cast<const char*>(key), 4);
    for (std::size_t i = 0; i < payload.size(); ++i) {
      frame.push_back(char(payload[i] ^ key[i % 4]));
    }
  } else {
    frame += payload;
  }
  if (!SendAll(fd_, frame.data(), frame.size())) {
    Close();
    return false;
  }
  return true;
}

bool WebSocket::Fill(int timeout_ms, bool* timed_out) {
  *timed_out = false;
  pollfd p{fd_, POLLIN, 0};
  int ready;
  do {
    ready = ::poll(&p, 1, timeout_ms);
  } while (ready < 0 && errno == EINTR);
  if (ready == 0) {
    *timed_out = true;
    return true;
  }
  char chunk[4096];
  const ssize_t n = ready > 0 ? ::recv(fd_, chunk, sizeof(chunk), 0) : -1;
  if (n <= 0) return false;
  reader_.Append(chunk, std::size_t(n));
  return true;
}

WebSocket::Status WebSocket::Receive(std::string* message, int timeout_ms) {
  const Clock::time_point deadline = Clock::now() + std::chrono::milliseconds(timeout_ms);
  bool filled = false;
  while (fd_ >= 0) {
    std::string payload;
    std::string problem;
    switch (reader_.Next(&payload, &problem)) {
      case WebSocketReader::Item::kMessage:
        *message = std::move(payload);
        return Status::kMessage;
      case WebSocketReader::Item::kPing:
        SendFrame(kPong, payload);
        break;
      case WebSocketReader::Item::kPong:
        break;
      case WebSocketReader::Item::kClose:
        SendFrame(kClose, "");
        Close();
        return Status::kClosed;
      case WebSocketReader::Item::kError:
        error_ = problem;
        Close();
        return Status::kClosed;
      case WebSocketReader::Item::kNeedMore: {
        // A peer trickling a frame byte by byte is cut off at the deadline
        // too; the part read stays buffered for the next call.
        if (filled && RemainingMs(deadline) == 0) return Status::kTimeout;
        filled = true;
        bool timed_out = false;
        if (!Fill(RemainingMs(deadline), &timed_out)) {
          Close();
          return Status::kClosed;
        }
        if (timed_out) return Status::kTimeout;
        continue;
      }
    }
    // Only control frames so far: a peer flooding them must not hold the
    // caller past its deadline.
    if (RemainingMs(deadline) == 0) return Status::kTimeout;
  }
  return Status::kClosed;
}

}  // namespace flysfm
