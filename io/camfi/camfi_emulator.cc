#include "io/camfi/camfi_emulator.h"

#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <deque>
#include <random>
#include <stdexcept>

#include <httplib.h>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <websocketpp/base64/base64.hpp>

#include "io/camfi/engineio_packet.h"
#include "io/camfi/websocket.h"
#include "io/sources/image_markers.h"

namespace flysfm {
namespace {

const std::vector<std::pair<CamfiFault, std::string>>& FaultTable() {
  static const std::vector<std::pair<CamfiFault, std::string>> table = {
      {CamfiFault::kDropSocket, "drop-socket"},  {CamfiFault::kStall, "stall"},
      {CamfiFault::kDuplicate, "duplicate"},     {CamfiFault::kMissing, "missing"},
      {CamfiFault::kOutOfOrder, "out-of-order"}, {CamfiFault::kTruncate, "truncate"},
      {CamfiFault::kHttp500, "http500"},         {CamfiFault::kAuth, "auth"},
      {CamfiFault::kLegacyInfo, "legacy-info"},  {CamfiFault::kTrickle, "trickle"}};
  return table;
}

void SendJson(httplib::Response& res, const nlohmann::json& body, int status = 200) {
  res.status = status;
  res.set_content(body.dump(), "application/json");
}

std::shared_ptr<const std::string> LoadAsJpeg(const std::filesystem::path& path) {
  const std::vector<std::uint8_t> bytes = ReadFileBytes(path);
  if (HasJpegMarkers(bytes)) {
    return std::make_shared<const std::string>(bytes.begin(), bytes.end());
  }
  const cv::Mat image = cv::imread(path.string(), cv::IMREAD_COLOR);
  std::vector<std::uint8_t> jpeg;
  if (image.empty() || !cv::imencode(".jpg", image, jpeg, {cv::IMWRITE_JPEG_QUALITY, 95})) {
    throw std::invalid_argument("cannot read " + path.string() + " as an image");
  }
  return std::make_shared<const std::string>(jpeg.begin(), jpeg.end());
}

}  // namespace

std::optional<CamfiFault> ParseCamfiFault(const std::string& name) {
  for (const auto& [fault, fault_name] : FaultTable()) {
    if (fault_name == name) return fault;
  }
  return std::nullopt;
}

std::string CamfiFaultName(CamfiFault fault) {
  for (const auto& [f, name] : FaultTable()) {
    if (f == fault) return name;
  }
  return "?";
}

std::vector<std::string> CamfiFaultNames() {
  std::vector<std::string> names;
  for (const auto& entry : FaultTable()) names.push_back(entry.second);
  return names;
}

bool CamfiEmulatorOptions::Check() const {
  const auto valid_port = [](int port) { return port >= 0 && port < 65536; };
  return !images.empty() && valid_port(http_port) && valid_port(event_port) &&
         interval_seconds >= 0 && ping_interval_ms > 0 && ping_timeout_ms > 0 &&
         (engine_io_version == 3 || engine_io_version == 4) && fault_every > 0 && !store.empty() &&
         store.front() == '/' && folder_size > 0 && folder_size <= 9999 && files_page_limit >= 0 &&
         files_failures >= 0;
}

struct CamfiEmulator::Connection {
  std::deque<std::string> outbox;
  bool stalled = false;
  bool dropped = false;
};

CamfiEmulator::CamfiEmulator(const CamfiEmulatorOptions& options)
    : options_(options), files_failures_left_(options.files_failures) {
  if (!options_.Check()) throw std::invalid_argument("invalid CAMFI emulator options");
  for (const std::filesystem::path& path : options_.images) images_.push_back(LoadAsJpeg(path));
  std::mt19937 random(options_.seed);
  for (const CamfiFault fault : options_.faults) {
    fault_offsets_[fault] =
        std::uniform_int_distribution<int>(0, options_.fault_every - 1)(random);
  }

  server_ = std::make_unique<httplib::Server>();
  SetUpRoutes();
  if (options_.http_port == 0) {
    http_port_ = server_->bind_to_any_port("127.0.0.1");
  } else if (server_->bind_to_port("127.0.0.1", options_.http_port)) {
    http_port_ = options_.http_port;
  }
  if (http_port_ <= 0) {
    throw std::runtime_error("cannot listen on 127.0.0.1:" + std::to_string(options_.http_port));
  }

  listen_fd_ = ::socket(AF_INET, SOCK_STREAM, 0);
  const int yes = 1;
  ::setsockopt(listen_fd_, SOL_SOCKET, SO_REUSEADDR, &yes, sizeof(yes));
  sockaddr_in address{};
  address.sin_family = AF_INET;
  address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  address.sin_port = htons(std::uint16_t(options_.event_port));
  socklen_t length = sizeof(address);
  if (listen_fd_ < 0 || ::bind(listen_fd_, reinterpret_cast<sockaddr*>(&address), length) != 0 ||
      ::listen(listen_fd_, 16) != 0 ||
      ::getsockname(listen_fd_, reinterpret_cast<sockaddr*>(&address), &length) != 0) {
    const std::string reason = std::strerror(errno);
    if (listen_fd_ >= 0) ::close(listen_fd_);
    server_->stop();
    throw std::runtime_error("cannot listen on 127.0.0.1:" +
                             std::to_string(options_.event_port) + ": " + reason);
  }
  event_port_ = ntohs(address.sin_port);

  http_thread_ = std::thread([this] { server_->listen_after_bind(); });
  // httplib's stop() does nothing before the server runs: a destructor
  // right after construction would otherwise wait forever.
  while (!server_->is_running()) std::this_thread::sleep_for(std::chrono::milliseconds(1));
  accept_thread_ = std::thread([this] { AcceptLoop(); });
  shot_thread_ = std::thread([this] { DriveShots(); });
}

CamfiEmulator::~CamfiEmulator() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stopping_ = true;
  }
  wake_.notify_all();
  server_->stop();
  http_thread_.join();
  accept_thread_.join();
  shot_thread_.join();
  for (std::thread& thread : connection_threads_) thread.join();
  ::close(listen_fd_);
}

std::string CamfiEmulator::DevicePath(int index) const {
  char file[32];
  std::snprintf(file, sizeof(file), "IMG_%04d.JPG", index % options_.folder_size + 1);
  return options_.store + "/DCIM/" + std::to_string(100 + index / options_.folder_size) +
         "CANON/" + file;
}

std::vector<std::string> CamfiEmulator::RequestLog() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return request_log_;
}

CamfiEmulatorStats CamfiEmulator::stats() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return stats_;
}

bool CamfiEmulator::Hits(CamfiFault fault, int shot) const {
  const auto found = fault_offsets_.find(fault);
  return found != fault_offsets_.end() &&
         (shot + found->second) % options_.fault_every == 0;
}

void CamfiEmulator::SetUpRoutes() {
  const std::string expected_auth =
      "Basic " + websocketpp::base64_encode("CamFi:" + options_.password);
  server_->set_pre_routing_handler(
      [this, expected_auth](const httplib::Request& req, httplib::Response& res) {
        std::lock_guard<std::mutex> lock(mutex_);
        request_log_.push_back(req.method + " " + req.target);
        if (options_.faults.count(CamfiFault::kAuth) &&
            req.get_header_value("Authorization") != expected_auth) {
          ++stats_.unauthorized;
          res.status = 401;
          res.set_header("WWW-Authenticate", "Basic realm=\"CamFi\"");
          return httplib::Server::HandlerResponse::Handled;
        }
        return httplib::Server::HandlerResponse::Unhandled;
      });
  server_->Get("/info", [this](const httplib::Request&, httplib::Response& res) {
    if (options_.faults.count(CamfiFault::kLegacyInfo)) {
      res.status = 404;
      return;
    }
    SendJson(res, {{"version", "3.0.0-emulator"}, {"serial", "EMU0000001"},
                   {"type", "pro"}, {"subtype", "plus"}});
  });
  server_->Get("/camera", [](const httplib::Request&, httplib::Response& res) {
    SendJson(res, {{"model", "Emulated EOS"}});
  });
  server_->Get("/config", [](const httplib::Request&, httplib::Response& res) {
    SendJson(res, {{"main",
                    {{"children",
                      {{"status",
                        {{"children", {{"cameramodel", {{"value", "Emulated EOS"}}}}}}}}}}}});
  });
  server_->Get(
      R"(/files/(\d+)/(\d+))", [this](const httplib::Request& req, httplib::Response& res) {
        const std::size_t start = options_.files_ignore_start ? 0 : std::stoul(req.matches[1]);
        std::size_t count = std::stoul(req.matches[2]);
        if (options_.files_page_limit > 0) {
          count = std::min(count, std::size_t(options_.files_page_limit));
        }
        nlohmann::json list = nlohmann::json::array();
        std::lock_guard<std::mutex> lock(mutex_);
        if (files_failures_left_ > 0) {
          --files_failures_left_;
          ++stats_.files_failed;
          res.status = options_.files_failure_status;
          res.set_content(options_.files_failure_body, "application/json");
          return;
        }
        for (std::size_t i = start; i < card_.size() && i < start + count; ++i) {
          list.push_back(card_[i]);
        }
        SendJson(res, list);
      });
  const auto serve_file = [this](const std::string& route) {
    return [this, route](const httplib::Request& req, httplib::Response& res) {
      // Routed on the target as received, not on httplib's decoded path:
      // the device path must arrive as one segment with "/" as %2F.
      const std::string tail = req.target.substr(route.size());
      if (options_.strict_path_encoding && tail.find('/') != std::string::npos) {
        SendJson(res, {{"message", "path not encoded as one segment"}}, 500);
        return;
      }
      const std::string device_path = httplib::detail::decode_url(tail, false);
      std::lock_guard<std::mutex> lock(mutex_);
      const auto found = card_index_.find(device_path);
      if (found == card_index_.end()) {
        SendJson(res, {{"message", "file not found"}}, 500);
        return;
      }
      const int shot = found->second;
      const std::shared_ptr<const std::string> bytes = images_[std::size_t(shot)];
      const auto first_download_hit = [&](CamfiFault fault) {
        return route == "/raw/" && Hits(fault, shot) &&
               download_fault_used_.insert({fault, shot}).second;
      };
      if (first_download_hit(CamfiFault::kHttp500)) {
        ++stats_.http_500;
        SendJson(res, {{"message", "camera busy"}}, 500);
        return;
      }
      if (first_download_hit(CamfiFault::kTrickle)) {
        ++stats_.bodies_trickled;
        res.set_content_provider(
            bytes->size(), "image/jpeg",
            [this, bytes](std::size_t offset, std::size_t, httplib::DataSink& sink) {
              for (int i = 0; i < 20 && !stopping_; ++i) {
                std::this_thread::sleep_for(std::chrono::milliseconds(50));
              }
              return !stopping_ && sink.write(bytes->data() + offset, 1);
            });
        return;
      }
      if (first_download_hit(CamfiFault::kTruncate)) {
        ++stats_.bodies_truncated;
        // The full Content-Length, half the bytes, then the connection ends.
        res.set_content_provider(
            bytes->size(), "image/jpeg",
            [bytes](std::size_t offset, std::size_t length, httplib::DataSink& sink) {
              const std::size_t half = bytes->size() / 2;
              if (offset >= half) return false;
              sink.write(bytes->data() + offset, std::min(length, half - offset));
              return true;
            });
        return;
      }
      if (route == "/raw/") ++stats_.raw_served;
      res.set_content(*bytes, "image/jpeg");
    };
  };
  // /image/ (preview) and /thumbnail/ serve the original too: their real
  // resolution is unknown (docs/camfi.md 2.1).
  server_->Get("/raw/.*", serve_file("/raw/"));
  server_->Get("/image/.*", serve_file("/image/"));
  server_->Get("/thumbnail/.*", serve_file("/thumbnail/"));
  server_->Post("/tether/start", [this](const httplib::Request&, httplib::Response& res) {
    std::lock_guard<std::mutex> lock(mutex_);
    tethered_ = true;
    SendJson(res, nlohmann::json::object());
  });
  server_->Post("/tether/stop", [this](const httplib::Request&, httplib::Response& res) {
    std::lock_guard<std::mutex> lock(mutex_);
    tethered_ = false;
    SendJson(res, nlohmann::json::object());
  });
  server_->Get("/takepic/true", [this](const httplib::Request&, httplib::Response& res) {
    Shoot();
    SendJson(res, nlohmann::json::object());
  });
  server_->Get("/live", [](const httplib::Request&, httplib::Response& res) {
    SendJson(res, nlohmann::json::object());
  });
}

void CamfiEmulator::AcceptLoop() {
  while (!stopping_) {
    pollfd p{listen_fd_, POLLIN, 0};
    if (::poll(&p, 1, 100) <= 0) continue;
    const int fd = ::accept(listen_fd_, nullptr, nullptr);
    if (fd < 0) continue;
    auto connection = std::make_shared<Connection>();
    connection_threads_.emplace_back([this, connection, fd] { Serve(connection, fd); });
  }
}

void CamfiEmulator::Serve(std::shared_ptr<Connection> connection, int fd) {
  std::string target;
  std::optional<WebSocket> socket = WebSocket::Accept(fd, 2000, &target);
  if (!socket) return;
  const std::string version = "EIO=" + std::to_string(options_.engine_io_version);
  if (target.compare(0, 11, "/socket.io/") != 0 || target.find(version) == std::string::npos ||
      target.find("transport=websocket") == std::string::npos) {
    return;
  }
  EngineIoOpen open;
  open.sid = "emulator" + std::to_string(fd);
  open.ping_interval_ms = options_.ping_interval_ms;
  open.ping_timeout_ms = options_.ping_timeout_ms;
  // socket.io 1.x/2.x servers join the default namespace on their own;
  // later ones wait for the client's "40".
  const bool server_pings = options_.engine_io_version >= 4;
  if (!socket->Send(FormatEngineIoOpen(open)) || (!server_pings && !socket->Send("40"))) {
    return;
  }
  const auto ping_interval = std::chrono::milliseconds(options_.ping_interval_ms);
  auto next_ping = std::chrono::steady_clock::now() + ping_interval;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    connections_.push_back(connection);
    client_seen_ = true;
  }
  wake_.notify_all();
  while (!stopping_) {
    std::string message;
    const WebSocket::Status status = socket->Receive(&message, 50);
    std::deque<std::string> outbox;
    bool stalled = false;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      if (connection->dropped) break;
      stalled = connection->stalled;
      if (!stalled) outbox.swap(connection->outbox);
      stats_.events_sent += int(outbox.size());
    }
    if (status == WebSocket::Status::kClosed) break;
    if (status == WebSocket::Status::kMessage && !stalled) {
      if (message == "2") socket->Send("3");
      if (message == "40" && server_pings) socket->Send("40{\"sid\":\"" + open.sid + "\"}");
    }
    if (server_pings && !stalled && std::chrono::steady_clock::now() >= next_ping) {
      socket->Send("2");
      next_ping += ping_interval;
    }
    for (const std::string& packet : outbox) socket->Send(packet);
  }
  socket->Close();
  std::lock_guard<std::mutex> lock(mutex_);
  connections_.erase(std::remove(connections_.begin(), connections_.end(), connection),
                     connections_.end());
}

void CamfiEmulator::DriveShots() {
  std::unique_lock<std::mutex> lock(mutex_);
  wake_.wait(lock, [this] { return client_seen_ || stopping_; });
  const auto interval = std::chrono::duration<double>(options_.interval_seconds);
  while (!stopping_ && next_shot_ < num_images()) {
    if (wake_.wait_for(lock, interval, [this] { return stopping_.load(); })) break;
    if (next_shot_ >= num_images()) break;
    if (tethered_) {
      FireLocked();
    } else {
      // A shutter press without tether mode: on the card, not announced.
      PutOnCardLocked();
    }
  }
}

void CamfiEmulator::Shoot() {
  std::lock_guard<std::mutex> lock(mutex_);
  if (next_shot_ < num_images()) FireLocked();
}

void CamfiEmulator::SwapCard() {
  std::lock_guard<std::mutex> lock(mutex_);
  card_.clear();
  card_index_.clear();
  card_files_ = 0;
}

void CamfiEmulator::SendPacket(const std::string& packet) {
  std::lock_guard<std::mutex> lock(mutex_);
  SendLocked({packet});
}

std::pair<int, std::string> CamfiEmulator::PutOnCardLocked() {
  const int shot = next_shot_++;
  std::string path = DevicePath(card_files_++);
  card_.push_back(path);
  card_index_[path] = shot;
  ++stats_.shots;
  return {shot, std::move(path)};
}

void CamfiEmulator::FireLocked() {
  const auto [shot, path] = PutOnCardLocked();
  if (Hits(CamfiFault::kDropSocket, shot) && !connections_.empty()) {
    for (const auto& connection : connections_) connection->dropped = true;
    ++stats_.sockets_dropped;
  }
  if (Hits(CamfiFault::kStall, shot) && !connections_.empty()) {
    for (const auto& connection : connections_) connection->stalled = true;
    ++stats_.sockets_stalled;
  }
  const std::string event = FormatSocketIoEvent("file_added", nlohmann::json::array({path}));
  std::vector<std::string> events;
  const bool last = next_shot_ >= num_images();
  // The event held back by the previous shot goes after this shot's.
  std::optional<std::string> held = std::move(held_event_);
  held_event_.reset();
  if (Hits(CamfiFault::kMissing, shot)) {
    ++stats_.events_missing;
  } else if (Hits(CamfiFault::kOutOfOrder, shot) && !held && !last) {
    held_event_ = event;
    ++stats_.events_reordered;
  } else {
    events.push_back(event);
    if (Hits(CamfiFault::kDuplicate, shot)) {
      events.push_back(event);
      ++stats_.events_duplicated;
    }
  }
  if (held) events.push_back(*held);
  SendLocked(events);
}

void CamfiEmulator::SendLocked(const std::vector<std::string>& events) {
  for (const auto& connection : connections_) {
    if (connection->dropped || connection->stalled) continue;
    connection->outbox.insert(connection->outbox.end(), events.begin(), events.end());
  }
}

}  // namespace flysfm
