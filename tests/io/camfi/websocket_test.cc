#include "io/camfi/websocket.h"

#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

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

}  // namespace
}  // namespace flysfm
