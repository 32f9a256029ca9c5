#include "io/view/view_server.h"

#include <arpa/inet.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <thread>

#include <catch2/catch.hpp>
#include <httplib.h>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>

namespace flysfm {
namespace {

using Clock = std::chrono::steady_clock;

ViewServerOptions TestOptions() {
  ViewServerOptions options;
  options.port = 0;
  options.keepalive_seconds = 0.1;
  return options;
}

// `n` points with ids from `first`, at x = id.
ViewUpdate Points(point3D_t first, int n, int total) {
  ViewUpdate update;
  for (int i = 0; i < n; ++i) {
    update.point_ids.push_back(first + i);
    update.xyz.insert(update.xyz.end(), {float(first + i), 0.f, 1.f});
    update.rgb.insert(update.rgb.end(), {10, 20, 30});
  }
  update.num_points = total;
  return update;
}

// A page's event stream, read with cpp-httplib's client on its own thread.
class EventClient {
 public:
  explicit EventClient(int port, const std::string& path = "/events") {
    thread_ = std::thread([this, port, path] {
      httplib::Client client("127.0.0.1", port);
      client.set_read_timeout(10, 0);
      client.Get(path.c_str(), [this](const char* data, std::size_t length) {
        std::lock_guard<std::mutex> lock(mutex_);
        buffer_.append(data, length);
        for (std::size_t end; (end = buffer_.find("\n\n")) != std::string::npos;) {
          const std::string event = buffer_.substr(0, end);
          buffer_.erase(0, end + 2);
          const std::size_t data_at = event.find("data: ");
          if (data_at != std::string::npos) {
            messages_.push_back(nlohmann::json::parse(event.substr(data_at + 6)));
          }
        }
        return !stop_;
      });
    });
  }
  ~EventClient() {
    stop_ = true;
    thread_.join();
  }
  // Waits for the n-th message (from 0); throws after `seconds`.
  nlohmann::json Message(std::size_t n, double seconds = 5) {
    const auto deadline = Clock::now() + std::chrono::duration<double>(seconds);
    while (Clock::now() < deadline) {
      {
        std::lock_guard<std::mutex> lock(mutex_);
        if (messages_.size() > n) return messages_[n];
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
    throw std::runtime_error("no message " + std::to_string(n));
  }

 private:
  std::mutex mutex_;
  std::string buffer_;
  std::vector<nlohmann::json> messages_;
  std::atomic<bool> stop_{false};
  std::thread thread_;
};

int ConnectRaw(int port) {
  const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in address{};
  address.sin_family = AF_INET;
  address.sin_port = htons(port);
  address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  REQUIRE(::connect(fd, reinterpret_cast<sockaddr*>(&address), sizeof(address)) == 0);
  return fd;
}

// What arrives on `fd` until `stop` is found in it or `seconds` pass.
std::string ReadUntil(int fd, const std::string& stop, double seconds) {
  std::string text;
  const auto deadline = Clock::now() + std::chrono::duration<double>(seconds);
  while (Clock::now() < deadline && text.find(stop) == std::string::npos) {
    pollfd p{fd, POLLIN, 0};
    if (::poll(&p, 1, 50) <= 0) continue;
    char buffer[65536];
    const ssize_t n = ::read(fd, buffer, sizeof(buffer));
    if (n <= 0) break;
    text.append(buffer, std::size_t(n));
  }
  return text;
}

std::size_t Count(const std::string& text, const std::string& what) {
  std::size_t count = 0;
  for (std::size_t at = text.find(what); at != std::string::npos; at = text.find(what, at + 1)) {
    ++count;
  }
  return count;
}

bool WaitForClients(const ViewServer& server, int n) {
  const auto deadline = Clock::now() + std::chrono::seconds(5);
  while (server.num_clients() < n) {
    if (Clock::now() > deadline) return false;
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  return true;
}

TEST_CASE("A page opened mid-run gets the whole model first and then what each image changed") {
  ViewServer server(TestOptions());
  ViewUpdate first = Points(1, 3, 3);
  ViewCamera camera;
  camera.image_id = 1;
  camera.camera_id = 1;
  camera.name = "a.jpg";
  first.cameras = {camera};
  first.num_images = 1;
  server.Publish(first);

  EventClient client(server.port());
  const nlohmann::json model = client.Message(0);
  CHECK(model["type"] == "model");
  CHECK(model["points"]["ids"] == nlohmann::json({1, 2, 3}));
  CHECK(model["cameras"].size() == 1);
  CHECK(model["counts"]["images"] == 1);

  ViewUpdate second = Points(4, 1, 3);
  second.removed_points = {2};
  server.Publish(second);
  const nlohmann::json update = client.Message(1);
  CHECK(update["type"] == "update");
  CHECK(update["points"]["ids"] == nlohmann::json({4}));
  CHECK(update["removed_points"] == nlohmann::json({2}));
  CHECK(update["cameras"].empty());
  CHECK(update["counts"]["points"] == 3);

  server.Finish(1.0);
  CHECK(client.Message(2)["type"] == "end");
}

TEST_CASE("A page opened after the run gets the model and the end") {
  ViewServer server(TestOptions());
  server.Publish(Points(1, 5, 5));
  server.Finish(0.0);
  EventClient client(server.port());
  CHECK(client.Message(0)["points"]["ids"].size() == 5);
  CHECK(client.Message(0)["finished"] == true);
  CHECK(client.Message(1)["type"] == "end");
}

TEST_CASE("A browser that never reads neither slows publishing nor misses the latest state") {
  ViewServerOptions options = TestOptions();
  options.max_queued_messages = 4;
  options.write_timeout_seconds = 30;
  ViewServer server(options);
  const int fd = ConnectRaw(server.port());
  const std::string request = "GET /events HTTP/1.1\r\nHost: test\r\n\r\n";
  REQUIRE(::write(fd, request.data(), request.size()) == ssize_t(request.size()));
  REQUIRE(WaitForClients(server, 1));

  // 200 updates of 5000 points, megabytes more than the socket buffers hold.
  const auto start = Clock::now();
  int total = 0;
  double slowest_ms = 0;
  for (int i = 0; i < 200; ++i) {
    total += 5000;
    const ViewUpdate update = Points(point3D_t(1 + i * 5000), 5000, total);
    const auto before = Clock::now();
    server.Publish(update);
    slowest_ms = std::max(
        slowest_ms, std::chrono::duration<double, std::milli>(Clock::now() - before).count());
  }
  const double seconds = std::chrono::duration<double>(Clock::now() - start).count();
  INFO("slowest Publish " << slowest_ms << " ms, all " << seconds << " s");
  // A publisher that wrote to the stalled socket would wait out the write
  // timeout in one Publish; serialising the updates takes its own time, which
  // a sanitizer build multiplies, so that is not what is bounded here.
  CHECK(slowest_ms < 1000 * options.write_timeout_seconds / 2);
  server.Finish(0.0);

  // Reading now: the stream skipped what overflowed and sent the model again.
  // The wait only guards against a hang: a sanitizer build takes tens of
  // seconds to write out a model of a million points.
  const std::string text = ReadUntil(fd, "{\"type\":\"end\"}", 180);
  ::close(fd);
  CHECK(Count(text, "{\"type\":\"model\"") >= 2);
  CHECK(Count(text, "{\"type\":\"update\"") < 200);
  const std::size_t last_model = text.rfind("{\"type\":\"model\"");
  REQUIRE(last_model != std::string::npos);
  CHECK(text.find("\"counts\":{\"images\":0,\"points\":" + std::to_string(total) + "}",
                  last_model) != std::string::npos);
  CHECK(text.find("{\"type\":\"end\"}") != std::string::npos);
}

TEST_CASE("On the network every request needs the printed token") {
  ViewServerOptions options = TestOptions();
  options.lan = true;
  options.token = "abc123";
  ViewServer server(options);
  CHECK(server.token() == "abc123");
  CHECK(server.Url().find("?token=abc123") != std::string::npos);
  httplib::Client client("127.0.0.1", server.port());
  for (const char* path : {"/", "/three.js", "/events", "/thumbnail.jpg", "/nothing"}) {
    INFO(path);
    const auto response = client.Get(path);
    REQUIRE(response);
    CHECK(response->status == 403);
    const auto wrong = client.Get((std::string(path) + "?token=abc124").c_str());
    REQUIRE(wrong);
    CHECK(wrong->status == 403);
  }
  const auto page = client.Get("/?token=abc123");
  REQUIRE(page);
  CHECK(page->status == 200);

  // Without a token of its own, a LAN view makes one, long enough not to guess.
  ViewServerOptions random = TestOptions();
  random.lan = true;
  CHECK(ViewServer(random).token().size() >= 32);
}

// One line for `name` with `status`.
ViewUpdate Line(const std::string& name, const std::string& status) {
  ViewUpdate update;
  ViewLine line;
  line.name = name;
  line.status = status;
  line.reason = status == "registered" ? "" : "why";
  update.lines.push_back(line);
  return update;
}

// The decoded thumbnail at /thumbnail.jpg?name=`name`; empty for a 404.
cv::Mat NamedThumbnail(httplib::Client& client, const std::string& name) {
  const auto response = client.Get(("/thumbnail.jpg?name=" + name).c_str());
  REQUIRE(response);
  if (response->status == 404) return cv::Mat();
  REQUIRE(response->status == 200);
  return cv::imdecode(std::vector<std::uint8_t>(response->body.begin(), response->body.end()),
                      cv::IMREAD_COLOR);
}

TEST_CASE("A pending or rejected shot keeps its thumbnail until it registers, in bounded number") {
  ViewServerOptions options = TestOptions();
  options.max_list_thumbnails = 2;
  ViewServer server(options);
  httplib::Client client("127.0.0.1", server.port());
  // Each shot its own grey level, so that a thumbnail shows whose it is.
  const auto shot = [](int grey) { return cv::Mat(300, 400, CV_8UC3, cv::Scalar::all(grey)); };
  const auto grey_of = [](const cv::Mat& image) { return int(cv::mean(image)[0] + 0.5); };

  server.SetLatestShot(shot(40), "a.jpg");
  server.Publish(Line("a.jpg", "pending"));
  // The latest answers by its name too.
  cv::Mat a = NamedThumbnail(client, "a.jpg");
  REQUIRE_FALSE(a.empty());
  CHECK(a.cols == 320);
  CHECK(std::abs(grey_of(a) - 40) <= 2);
  server.SetLatestShot(shot(90), "b.jpg");
  server.Publish(Line("b.jpg", "registered"));
  // a.jpg waits: its picture stayed though the latest is b.jpg.
  a = NamedThumbnail(client, "a.jpg");
  REQUIRE_FALSE(a.empty());
  CHECK(std::abs(grey_of(a) - 40) <= 2);
  server.SetLatestShot(shot(140), "c.jpg");
  // b.jpg registered: nothing kept of it, and the latest is not b's.
  CHECK(NamedThumbnail(client, "b.jpg").empty());
  server.Publish(Line("c.jpg", "rejected"));
  server.SetLatestShot(shot(190), "d.jpg");
  const cv::Mat c = NamedThumbnail(client, "c.jpg");
  REQUIRE_FALSE(c.empty());
  CHECK(std::abs(grey_of(c) - 140) <= 2);
  CHECK(NamedThumbnail(client, "nothing.jpg").empty());

  // a.jpg registers later: its picture goes.
  server.Publish(Line("a.jpg", "registered"));
  CHECK(NamedThumbnail(client, "a.jpg").empty());
  CHECK_FALSE(NamedThumbnail(client, "c.jpg").empty());

  // Past max_list_thumbnails the oldest goes first.
  server.Publish(Line("d.jpg", "pending"));
  server.SetLatestShot(shot(220), "e.jpg");
  server.Publish(Line("e.jpg", "pending"));
  server.SetLatestShot(shot(250), "f.jpg");
  CHECK(NamedThumbnail(client, "c.jpg").empty());
  CHECK_FALSE(NamedThumbnail(client, "d.jpg").empty());
  CHECK_FALSE(NamedThumbnail(client, "e.jpg").empty());
}

TEST_CASE("The page and three.js and the thumbnail are served and bad requests get a 4xx") {
  ViewServer server(TestOptions());
  httplib::Client client("127.0.0.1", server.port());
  const auto page = client.Get("/");
  REQUIRE(page);
  CHECK(page->status == 200);
  CHECK(page->body.find("flysfmView") != std::string::npos);
  const auto three = client.Get("/three.js");
  REQUIRE(three);
  CHECK(three->body.find("REVISION") != std::string::npos);
  const auto orbit = client.Get("/orbit.js");
  REQUIRE(orbit);
  CHECK(orbit->body.find("OrbitControls") != std::string::npos);

  const auto none = client.Get("/thumbnail.jpg");
  REQUIRE(none);
  CHECK(none->status == 404);
  server.SetLatestShot(cv::Mat(750, 1000, CV_8UC3, cv::Scalar(10, 200, 30)));
  const auto shot = client.Get("/thumbnail.jpg");
  REQUIRE(shot);
  CHECK(shot->status == 200);
  const cv::Mat thumbnail =
      cv::imdecode(std::vector<std::uint8_t>(shot->body.begin(), shot->body.end()),
                   cv::IMREAD_COLOR);
  CHECK(thumbnail.cols == 320);
  CHECK(thumbnail.rows == 240);

  const auto missing = client.Get("/etc/passwd");
  REQUIRE(missing);
  CHECK(missing->status == 404);
  const auto post = client.Post("/events", "x", "text/plain");
  REQUIRE(post);
  CHECK(post->status >= 400);
  CHECK(post->status < 500);

  for (const std::string& garbage :
       {std::string("GARBAGE\r\n\r\n"), std::string("GET /") + std::string(20000, 'a') +
                                            " HTTP/1.1\r\nHost: x\r\n\r\n",
        std::string("POST /events HTTP/1.1\r\nHost: x\r\nContent-Length: 99999999\r\n\r\n")}) {
    const int fd = ConnectRaw(server.port());
    REQUIRE(::write(fd, garbage.data(), garbage.size()) == ssize_t(garbage.size()));
    // cpp-httplib answers a body beyond its bound once it has waited out
    // the server's 5 s read timeout for it; the wait here only guards
    // against a hang.
    const std::string answer = ReadUntil(fd, "\r\n", 30);
    ::close(fd);
    INFO(garbage.substr(0, 40));
    REQUIRE(answer.size() >= 12);
    CHECK(answer.substr(0, 9) == "HTTP/1.1 ");
    CHECK(answer[9] == '4');
  }
}

TEST_CASE("Event streams beyond the bound are refused and not queued") {
  ViewServerOptions options = TestOptions();
  options.max_clients = 1;
  ViewServer server(options);
  EventClient first(server.port());
  first.Message(0);
  httplib::Client client("127.0.0.1", server.port());
  const auto second = client.Get("/events");
  REQUIRE(second);
  CHECK(second->status == 503);
}

TEST_CASE("Bad view options are refused with their name") {
  ViewServerOptions options;
  options.port = 70000;
  CHECK_THROWS_WITH(options.Check(), Catch::Contains("port"));
  options = ViewServerOptions();
  options.token = "a b";
  CHECK_THROWS_WITH(options.Check(), Catch::Contains("token"));
  options = ViewServerOptions();
  options.max_list_thumbnails = -1;
  CHECK_THROWS_WITH(options.Check(), Catch::Contains("max_list_thumbnails"));
  options = ViewServerOptions();
  options.three_js = "/nonexistent/three.js";
  options.port = 0;
  CHECK_THROWS_WITH(ViewServer(options), Catch::Contains("libjs-three"));
}

}  // namespace
}  // namespace flysfm
