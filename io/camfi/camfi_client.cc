#include "io/camfi/camfi_client.h"

#include <algorithm>
#include <cctype>
#include <iostream>
#include <random>
#include <sstream>
#include <stdexcept>

#include <nlohmann/json.hpp>

#include "io/camfi/engineio_packet.h"
#include "io/camfi/websocket.h"
#include "io/formats/atomic_file.h"
#include "io/sources/image_markers.h"

namespace flysfm {
namespace {

using Clock = std::chrono::steady_clock;

constexpr const char* kJournalName = "journal.tsv";

double SecondsSince(Clock::time_point t) {
  return std::chrono::duration<double>(Clock::now() - t).count();
}

std::string Lower(std::string text) {
  std::transform(text.begin(), text.end(), text.begin(),
                 [](unsigned char c) { return char(std::tolower(c)); });
  return text;
}

}  // namespace

bool CamfiOptions::Check() const {
  const auto valid_port = [](int port) { return port > 0 && port < 65536; };
  return !host.empty() && valid_port(http_port) && valid_port(event_port) &&
         reconcile_seconds > 0 && list_page > 0 && retries > 0 && control_timeout > 0 &&
         list_timeout > 0 && download_idle_seconds > 0 && backoff_min_seconds > 0 &&
         backoff_max_seconds >= backoff_min_seconds && ping_interval_override_ms >= 0 &&
         ping_timeout_override_ms >= 0 && !cache_route.empty() &&
         (engine_io_version == 3 || engine_io_version == 4);
}

std::string StoreNameForDevicePath(const std::string& device_path) {
  std::string name = device_path;
  while (!name.empty() && name.front() == '/') name.erase(0, 1);
  for (char& c : name) {
    const auto byte = static_cast<unsigned char>(c);
    if (!(std::isalnum(byte) || c == '-' || c == '.' || c == '_')) c = '_';
  }
  return name;
}

CamfiSource::CamfiSource(const CamfiOptions& options, const std::filesystem::path& store_dir)
    : options_(options),
      store_dir_(store_dir),
      http_(options.host, options.http_port, options.password) {
  if (!options_.Check()) throw std::invalid_argument("invalid CAMFI options");
  std::error_code error;
  std::filesystem::create_directories(store_dir_, error);
  if (error) {
    throw std::runtime_error("cannot create the image store " + store_dir_.string() + ": " +
                             error.message());
  }
  ReadJournal();
  journal_.open(store_dir_ / kJournalName, std::ios::app);
  if (!journal_) {
    throw std::runtime_error("cannot write " + (store_dir_ / kJournalName).string());
  }
  session_thread_ = std::thread([this] { SessionLoop(); });
  download_thread_ = std::thread([this] { DownloadLoop(); });
}

CamfiSource::~CamfiSource() {
  Stop();
  session_thread_.join();
  download_thread_.join();
}

void CamfiSource::Stop() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stopping_ = true;
  }
  wake_.notify_all();
}

void CamfiSource::Log(const std::string& message) const {
  std::ostringstream line;
  line << "camfi: " << message << "\n";
  std::cerr << line.str() << std::flush;
}

CamfiStats CamfiSource::stats() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return stats_;
}

std::vector<std::string> CamfiSource::StoredDevicePaths() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return stored_paths_;
}

// The journal is tab-separated, one record a line, appended and flushed
// after the file it names is complete:
//   baseline                      the first listing of a fresh store is done
//   ignored <device path>         on the card before the session began
//   stored <device path> <name> <bytes>
// A line cut by a crash has too few fields and is skipped.
void CamfiSource::ReadJournal() {
  std::ifstream in(store_dir_ / kJournalName);
  std::string line;
  while (std::getline(in, line)) {
    std::vector<std::string> fields;
    std::stringstream stream(line);
    std::string field;
    while (std::getline(stream, field, '\t')) fields.push_back(field);
    if (fields.empty()) continue;
    if (fields[0] == "baseline") {
      baseline_done_ = true;
    } else if (fields[0] == "ignored" && fields.size() == 2) {
      known_.insert(fields[1]);
    } else if (fields[0] == "stored" && fields.size() == 4) {
      const std::filesystem::path file = store_dir_ / fields[2];
      const std::vector<std::uint8_t> bytes = ReadFileBytes(file);
      if (bytes.size() != std::stoull(fields[3]) || !LooksCompleteImage(file, bytes)) {
        Log("journal names " + file.string() + " but the file is missing or damaged; "
            "it will be fetched again");
        continue;
      }
      if (!known_.insert(fields[1]).second) continue;
      Frame frame;
      frame.name = fields[2];
      frame.path = file;
      frame.timestamp = double(stored_paths_.size());
      frame.arrival = Clock::now();
      ready_.push_back(std::move(frame));
      stored_paths_.push_back(fields[1]);
      ++stats_.replayed;
    }
  }
  // Temporary files of writes a crash interrupted.
  for (const auto& entry : std::filesystem::directory_iterator(store_dir_)) {
    if (entry.path().extension() == ".tmp") std::filesystem::remove(entry.path());
  }
}

void CamfiSource::AppendJournal(const std::string& line) {
  journal_ << line << "\n";
  journal_.flush();
  if (!journal_) throw std::runtime_error("cannot append to the journal in " + store_dir_.string());
}

std::optional<Frame> CamfiSource::Next() {
  std::unique_lock<std::mutex> lock(mutex_);
  wake_.wait(lock, [this] { return !ready_.empty() || stopping_; });
  if (ready_.empty()) return std::nullopt;
  Frame frame = std::move(ready_.front());
  ready_.pop_front();
  return frame;
}

bool CamfiSource::Wait(double seconds) {
  std::unique_lock<std::mutex> lock(mutex_);
  return !wake_.wait_for(lock, std::chrono::duration<double>(seconds),
                         [this] { return stopping_.load(); });
}

void CamfiSource::Offer(const std::string& device_path, bool from_event,
                        Clock::time_point arrival) {
  const std::string extension = Lower(std::filesystem::path(device_path).extension().string());
  const bool wanted = std::find(options_.extensions.begin(), options_.extensions.end(),
                                extension) != options_.extensions.end() &&
                      std::find(options_.ignore_paths.begin(), options_.ignore_paths.end(),
                                device_path) == options_.ignore_paths.end();
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (from_event) ++stats_.events;
    if (!wanted) return;
    if (!known_.insert(device_path).second) {
      if (from_event) ++stats_.duplicate_events;
      return;
    }
    if (!from_event) ++stats_.found_by_listing;
    queue_.push_back({device_path, arrival});
  }
  wake_.notify_all();
}

void CamfiSource::SessionLoop() {
  double backoff = options_.backoff_min_seconds;
  std::mt19937 random(std::random_device{}());
  while (!stopping_) {
    const Clock::time_point started = Clock::now();
    try {
      RunSession();
    } catch (const std::exception& e) {
      if (stopping_) break;
      Log(std::string("session ended: ") + e.what());
    }
    if (stopping_) break;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      ++stats_.session_failures;
    }
    // A session that ran a while was healthy: start the back-off over.
    if (SecondsSince(started) > 2 * options_.backoff_max_seconds) {
      backoff = options_.backoff_min_seconds;
    }
    const double jitter = std::uniform_real_distribution<double>(0.8, 1.2)(random);
    if (!Wait(backoff * jitter)) break;
    backoff = std::min(2 * backoff, options_.backoff_max_seconds);
  }
}

void CamfiSource::RunSession() {
  const HttpResult info = http_.Get("/info", options_.control_timeout, 0, &stopping_);
  if (info.status == 404) {
    // Firmware older than /info (camfi.md 1): version 1.0.0.0.
  } else if (info.status == 401) {
    throw std::runtime_error("the device asks for a password (--camfi-password)");
  } else if (info.status != 200) {
    throw std::runtime_error("no answer from " + options_.host + ":" +
                             std::to_string(options_.http_port) + "/info: " +
                             (info.error.empty() ? "HTTP " + std::to_string(info.status)
                                                 : info.error));
  }
  const HttpResult camera = http_.Get("/camera", options_.control_timeout, 0, &stopping_);
  if (camera.status == 200) {
    const nlohmann::json body = nlohmann::json::parse(camera.BodyText(), nullptr, false);
    if (!body.is_object() || !body.contains("model") || !body["model"].is_string() ||
        body["model"].get<std::string>().empty()) {
      Log("no camera connected to the transmitter yet");
    }
  }
  bool baseline = false;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    baseline = !baseline_done_ && !options_.fetch_existing;
  }
  // The baseline listing comes before the event channel opens: a shot taken
  // after it is then either announced or found by the next listing.
  if (baseline) Reconcile(/*baseline=*/true);

  WebSocket socket = WebSocket::Connect(options_.host, options_.event_port,
                                        EngineIoResource(options_.engine_io_version),
                                        int(1000 * options_.control_timeout));
  std::string packet;
  if (socket.Receive(&packet, int(1000 * options_.control_timeout)) !=
      WebSocket::Status::kMessage) {
    throw std::runtime_error("the event channel sent no open packet");
  }
  const std::optional<EngineIoOpen> open = ParseEngineIoOpen(packet);
  if (!open) throw std::runtime_error("the event channel's first packet is not an open packet");
  // socket.io 1.x/2.x servers join the default namespace on their own.
  const bool client_pings = options_.engine_io_version == 3;
  if (!client_pings) socket.Send("40");
  const auto ping_interval = std::chrono::milliseconds(
      options_.ping_interval_override_ms > 0 ? options_.ping_interval_override_ms
                                             : open->ping_interval_ms);
  const auto ping_timeout = std::chrono::milliseconds(
      options_.ping_timeout_override_ms > 0 ? options_.ping_timeout_override_ms
                                            : open->ping_timeout_ms);
  {
    std::lock_guard<std::mutex> lock(mutex_);
    ++stats_.sessions;
  }
  const auto arm = [&] {
    if (!options_.tether_on_connect) return;
    const HttpResult tether = http_.Post("/tether/start", options_.control_timeout);
    if (tether.status != 200) {
      Log("/tether/start failed (" +
          (tether.error.empty() ? "HTTP " + std::to_string(tether.status) : tether.error) +
          "); only remote-triggered shots may be announced");
    }
  };
  arm();
  Reconcile(/*baseline=*/false);

  Clock::time_point last_packet = Clock::now();
  Clock::time_point next_ping =
      client_pings ? Clock::now() + ping_interval : Clock::time_point::max();
  Clock::time_point next_reconcile =
      Clock::now() + std::chrono::duration_cast<Clock::duration>(
                         std::chrono::duration<double>(options_.reconcile_seconds));
  while (!stopping_) {
    const Clock::time_point now = Clock::now();
    const Clock::time_point until =
        std::min({next_ping, next_reconcile, now + std::chrono::milliseconds(200)});
    const int wait_ms =
        int(std::max<long long>(1, std::chrono::duration_cast<std::chrono::milliseconds>(
                                       until - now).count()));
    const WebSocket::Status status = socket.Receive(&packet, wait_ms);
    if (status == WebSocket::Status::kClosed) {
      throw std::runtime_error("the event channel closed");
    }
    if (status == WebSocket::Status::kMessage) {
      last_packet = Clock::now();
      if (packet == "1" || packet == "41") throw std::runtime_error("the device closed the session");
      if (packet == "2") socket.Send("3");
      if (const std::optional<SocketIoEvent> event = ParseSocketIoEvent(packet)) {
        if (event->name == "file_added" && !event->args.empty() && event->args[0].is_string()) {
          Offer(event->args[0].get<std::string>(), /*from_event=*/true, last_packet);
        } else if (event->name == "camera_add") {
          arm();
          Reconcile(/*baseline=*/false);
        }
      }
    }
    if (client_pings && Clock::now() >= next_ping) {
      if (!socket.Send("2")) throw std::runtime_error("the event channel closed");
      next_ping = Clock::now() + ping_interval;
    }
    if (Clock::now() - last_packet > ping_interval + ping_timeout) {
      throw std::runtime_error("no packet on the event channel for " +
                               std::to_string((ping_interval + ping_timeout).count()) +
                               " ms (stale socket)");
    }
    if (Clock::now() >= next_reconcile) {
      Reconcile(/*baseline=*/false);
      next_reconcile = Clock::now() + std::chrono::duration_cast<Clock::duration>(
                                          std::chrono::duration<double>(options_.reconcile_seconds));
    }
  }
}

void CamfiSource::Reconcile(bool baseline) {
  std::vector<std::string> paths;
  for (int start = 0;; start += options_.list_page) {
    const HttpResult page = http_.Get(
        "/files/" + std::to_string(start) + "/" + std::to_string(options_.list_page),
        options_.list_timeout, 0, &stopping_);
    if (page.status != 200) {
      throw std::runtime_error("listing /files failed: " +
                               (page.error.empty() ? "HTTP " + std::to_string(page.status)
                                                   : page.error));
    }
    const nlohmann::json list = nlohmann::json::parse(page.BodyText(), nullptr, false);
    if (!list.is_array()) throw std::runtime_error("/files did not answer a JSON array");
    for (const nlohmann::json& entry : list) {
      if (entry.is_string()) paths.push_back(entry.get<std::string>());
    }
    // The order of /files is not documented: page until a short page.
    if (int(list.size()) < options_.list_page) break;
  }
  if (!baseline) {
    for (const std::string& path : paths) Offer(path, /*from_event=*/false, Clock::now());
    return;
  }
  std::lock_guard<std::mutex> lock(mutex_);
  for (const std::string& path : paths) {
    if (known_.insert(path).second) AppendJournal("ignored\t" + path);
  }
  AppendJournal("baseline");
  baseline_done_ = true;
}

void CamfiSource::DownloadLoop() {
  while (true) {
    Pending item;
    {
      std::unique_lock<std::mutex> lock(mutex_);
      wake_.wait(lock, [this] { return !queue_.empty() || stopping_; });
      if (stopping_) return;
      item = queue_.front();
      queue_.pop_front();
    }
    std::vector<std::uint8_t> bytes;
    bool done = false;
    double retry_wait = 0.25;
    for (int attempt = 0; attempt < options_.retries && !stopping_; ++attempt) {
      if (Download(item.device_path, &bytes)) {
        done = true;
        break;
      }
      if (!Wait(retry_wait)) break;
      retry_wait = std::min(2 * retry_wait, 4.0);
    }
    if (stopping_) return;
    if (done) {
      try {
        Store(item.device_path, bytes, item.arrival);
      } catch (const std::exception& e) {
        Log(e.what());
        done = false;
      }
    }
    if (!done) {
      Log(item.device_path + " not fetched after " + std::to_string(options_.retries) +
          " attempts; retried after the next listing");
      std::lock_guard<std::mutex> lock(mutex_);
      known_.erase(item.device_path);
    }
  }
}

bool CamfiSource::Download(const std::string& device_path, std::vector<std::uint8_t>* bytes) {
  const bool cached = !options_.cache_prefix.empty() &&
                      device_path.compare(0, options_.cache_prefix.size(),
                                          options_.cache_prefix) == 0;
  const std::string target =
      (cached ? options_.cache_route : std::string("/raw/")) + EncodeDevicePath(device_path);
  HttpResult result =
      http_.Get(target, options_.control_timeout, options_.download_idle_seconds, &stopping_);
  std::string problem;
  if (!result.error.empty()) {
    problem = result.error;
  } else if (result.status != 200) {
    problem = "HTTP " + std::to_string(result.status);
    const nlohmann::json body = nlohmann::json::parse(result.BodyText(), nullptr, false);
    if (body.is_object() && body.contains("message") && body["message"].is_string()) {
      problem += " (" + body["message"].get<std::string>() + ")";
    }
  } else if (result.content_length >= 0 &&
             result.body.size() != std::size_t(result.content_length)) {
    problem = std::to_string(result.body.size()) + " bytes of " +
              std::to_string(result.content_length);
  } else if (!HasJpegMarkers(result.body)) {
    problem = "not a complete JPEG (start/end markers missing)";
  }
  if (!problem.empty()) {
    if (!stopping_) Log("download of " + device_path + " rejected: " + problem);
    std::lock_guard<std::mutex> lock(mutex_);
    ++stats_.download_failures;
    return false;
  }
  *bytes = std::move(result.body);
  return true;
}

void CamfiSource::Store(const std::string& device_path, const std::vector<std::uint8_t>& bytes,
                        Clock::time_point arrival) {
  const std::string name = StoreNameForDevicePath(device_path);
  const std::filesystem::path file = store_dir_ / name;
  WriteFileAtomically(
      file,
      [&](std::ostream& out) {
        out.write(reinterpret_cast<const char*>(bytes.data()), std::streamsize(bytes.size()));
      },
      /*binary=*/true);
  {
    std::lock_guard<std::mutex> lock(mutex_);
    // Stopped meanwhile: Next() may have ended already, so the shot is left
    // for the next run to fetch rather than journalled and never processed.
    if (stopping_) {
      std::filesystem::remove(file);
      return;
    }
    AppendJournal("stored\t" + device_path + "\t" + name + "\t" + std::to_string(bytes.size()));
    Frame frame;
    frame.name = name;
    frame.path = file;
    frame.timestamp = double(stored_paths_.size());
    frame.arrival = arrival;
    ready_.push_back(std::move(frame));
    stored_paths_.push_back(device_path);
    ++stats_.stored;
  }
  wake_.notify_all();
}

}  // namespace flysfm
