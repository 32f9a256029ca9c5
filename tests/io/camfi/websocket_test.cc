#include "io/camfi/websocket.h"

#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <functional>
#include <string>
#include <thread>
#include <vector>

#include <catch2/catch.hpp>

namespace flysfm {
namespace {

// A listening socket on an ephemeral loopback port.
int Listen(int* port) {
  const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in address{};
  address.sin_family = AF_INET;
  address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  socklen_t length = sizeof(address);
  REQUIRE(::bind(fd, reinterpret_cast<sockaddr*>(&address), length) == 0);
  REQUIRE(::listen(fd, 4) == 0);
  REQUIRE(::getsockname(fd, reinterpret_cast<sockaddr*>(&address), &length) == 0);
  *port = ntohs(address.sin_port);
  return fd;
}

// An unmasked server frame: FIN bit `fin`, `opcode`, `payload`.
std::string Frame(bool fin, int opcode, const std::string& payload) {
  std::string frame(1, char((fin ? 0x80 : 0) | opcode));
  if (payload.size() < 126) {
    frame.push_back(char(payload.size()));
  } else {
    frame.push_back(char(127));
    for (int shift = 56; shift >= 0; shift -= 8) {
      frame.push_back(char((std::uint64_t(payload.size()) >> shift) & 0xFF));
    }
  }
  return frame + payload;
}

// Accepts one client on `listen_fd`, completes the handshake, then writes
// `frames(0)`, `frames(1)`, ... raw on the connection until `frames` returns
// "", a write fails (the client dropped it) or `seconds` passed.
std::thread Flood(int listen_fd, std::function<std::string(int)> frames, double seconds) {
  return std::thread([listen_fd, frames, seconds] {
    const int fd = ::accept(listen_fd, nullptr, nullptr);
    const int raw = ::dup(fd);
    std::string target;
    std::optional<WebSocket> socket = WebSocket::Accept(fd, 2000, &target);
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::duration<double>(seconds);
    for (int i = 0; socket && std::chrono::steady_clock::now() < deadline; ++i) {
      const std::string frame = frames(i);
      if (frame.empty() ||
          ::send(raw, frame.data(), frame.size(), MSG_NOSIGNAL) != ssize_t(frame.size())) {
        break;
      }
    }
    ::close(raw);
  });
}

TEST_CASE("WebSocketAcceptKey matches RFC 6455's example") {
  CHECK(WebSocketAcceptKey("dGhlIHNhbXBsZSBub25jZQ==") == "s3pPLMBiTxaQ9kYGzzhZRbK+xOo=");
}

TEST_CASE("WebSocket carries messages of every length class both ways") {
  int port = 0;
  const int listen_fd = Listen(&port);
  const std::string medium(300, 'm');
  const std::string large(70000, 'L');
  std::string target;
  // Catch2's assertions are not thread-safe: the server thread only records
  // what it received, and the test checks that after join().
  std::vector<std::string> received;
  std::thread server([&] {
    const int fd = ::accept(listen_fd, nullptr, nullptr);
    std::optional<WebSocket> socket = WebSocket::Accept(fd, 2000, &target);
    if (!socket) return;
    std::string message;
    while (received.size() < 3 &&
           socket->Receive(&message, 2000) == WebSocket::Status::kMessage) {
      received.push_back(message);
      socket->Send("echo:" + message);
    }
    // Then silence, and a dropped link.
    std::this_thread::sleep_for(std::chrono::milliseconds(300));
    socket->Close();
  });
  WebSocket client = WebSocket::Connect("127.0.0.1", port, "/socket.io/?EIO=3", 2000);
  std::string reply;
  for (const std::string& message : {std::string("2"), medium, large}) {
    REQUIRE(client.Send(message));
    REQUIRE(client.Receive(&reply, 2000) == WebSocket::Status::kMessage);
    CHECK(reply == "echo:" + message);
  }
  CHECK(client.Receive(&reply, 100) == WebSocket::Status::kTimeout);
  CHECK(client.Receive(&reply, 2000) == WebSocket::Status::kClosed);
  CHECK_FALSE(client.is_open());
  server.join();
  CHECK(target == "/socket.io/?EIO=3");
  CHECK(received == std::vector<std::string>{"2", medium, large});
  ::close(listen_fd);
}

TEST_CASE("WebSocket::Connect fails clearly without a server") {
  int port = 0;
  const int listen_fd = Listen(&port);
  ::close(listen_fd);
  CHECK_THROWS_WITH(WebSocket::Connect("127.0.0.1", port, "/", 500),
                    Catch::Contains("cannot connect"));
}

TEST_CASE("WebSocket::Connect rejects a plain HTTP answer") {
  int port = 0;
  const int listen_fd = Listen(&port);
  std::thread server([&] {
    const int fd = ::accept(listen_fd, nullptr, nullptr);
    char buffer[2048];
    (void)::recv(fd, buffer, sizeof(buffer), 0);
    const std::string answer = "HTTP/1.1 404 Not Found\r\nContent-Length: 0\r\n\r\n";
    (void)::send(fd, answer.data(), answer.size(), 0);
    ::close(fd);
  });
  CHECK_THROWS_WITH(WebSocket::Connect("127.0.0.1", port, "/", 2000),
                    Catch::Contains("refused"));
  server.join();
  ::close(listen_fd);
}

TEST_CASE("WebSocket drops a message over its bound, said in error()") {
  int port = 0;
  const int listen_fd = Listen(&port);
  std::thread server = Flood(
      listen_fd,
      [](int i) { return i == 0 ? Frame(true, 0x1, std::string(2u << 20, 'x')) : std::string(); },
      5);
  WebSocket client = WebSocket::Connect("127.0.0.1", port, "/", 2000, 1u << 20);
  std::string message;
  CHECK(client.Receive(&message, 3000) == WebSocket::Status::kClosed);
  CHECK_THAT(client.error(), Catch::Contains("over 1048576 bytes"));
  CHECK(message.empty());
  server.join();
  ::close(listen_fd);
}

TEST_CASE("WebSocket drops an endless fragment stream once it passes the bound") {
  int port = 0;
  const int listen_fd = Listen(&port);
  const std::string chunk(64 << 10, 'f');
  std::thread server = Flood(
      listen_fd, [&](int i) { return Frame(false, i == 0 ? 0x1 : 0x0, chunk); }, 5);
  WebSocket client = WebSocket::Connect("127.0.0.1", port, "/", 2000, 1u << 20);
  std::string message;
  const auto start = std::chrono::steady_clock::now();
  WebSocket::Status status = WebSocket::Status::kTimeout;
  while (status == WebSocket::Status::kTimeout &&
         std::chrono::steady_clock::now() - start < std::chrono::seconds(4)) {
    status = client.Receive(&message, 500);
  }
  CHECK(status == WebSocket::Status::kClosed);
  CHECK_THAT(client.error(), Catch::Contains("over 1048576 bytes"));
  server.join();
  ::close(listen_fd);
}

TEST_CASE("WebSocket::Receive returns on time under a flood of pings") {
  int port = 0;
  const int listen_fd = Listen(&port);
  std::thread server = Flood(
      listen_fd, [](int) { return Frame(true, 0x9, "p"); }, 3);
  WebSocket client = WebSocket::Connect("127.0.0.1", port, "/", 2000);
  std::string message;
  const auto start = std::chrono::steady_clock::now();
  CHECK(client.Receive(&message, 200) == WebSocket::Status::kTimeout);
  CHECK(std::chrono::steady_clock::now() - start < std::chrono::milliseconds(1000));
  client.Close();
  server.join();
  ::close(listen_fd);
}

TEST_CASE("WebSocketReader enforces RFC 6455's frame rules") {
  std::string payload;
  std::string error;
  const auto first_item = [&](const std::string& bytes) {
    WebSocketReader reader(1000);
    reader.Append(bytes.data(), bytes.size());
    return reader.Next(&payload, &error);
  };
  CHECK(first_item(Frame(true, 0x1, "hi")) == WebSocketReader::Item::kMessage);
  CHECK(payload == "hi");
  CHECK(first_item(Frame(false, 0x1, "a") + Frame(true, 0x0, "b")) ==
        WebSocketReader::Item::kMessage);
  CHECK(payload == "ab");
  CHECK(first_item(Frame(true, 0x9, std::string(126, 'p'))) == WebSocketReader::Item::kError);
  CHECK(first_item(Frame(false, 0x9, "p")) == WebSocketReader::Item::kError);
  CHECK(first_item(Frame(true, 0x0, "orphan")) == WebSocketReader::Item::kError);
  CHECK(first_item(Frame(false, 0x1, "a") + Frame(true, 0x1, "b")) ==
        WebSocketReader::Item::kError);
  CHECK(first_item(Frame(true, 0x3, "")) == WebSocketReader::Item::kError);
  CHECK(first_item(std::string(1, char(0xC1)) + std::string(1, char(0))) ==
        WebSocketReader::Item::kError);
  // An announced length over the bound is refused on the header alone.
  const std::string header = Frame(true, 0x1, std::string(2000, 'x')).substr(0, 10);
  CHECK(first_item(header) == WebSocketReader::Item::kError);
  CHECK_THAT(error, Catch::Contains("over 1000 bytes"));
  // Fragments count together.
  CHECK(first_item(Frame(false, 0x1, std::string(600, 'a')) +
                   Frame(true, 0x0, std::string(600, 'b'))) == WebSocketReader::Item::kError);
}

}  // namespace
}  // namespace flysfm
