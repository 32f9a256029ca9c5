#include "io/camfi/camfi_client.h"

#include <algorithm>
#include <cctype>
#include <iostream>
#include <random>
#include <sstream>
#include <stdexcept>

#include <websocketpp/sha1/sha1.hpp>

#include "io/camfi/camfi_listing.h"
#include "io/camfi/engineio_packet.h"
#include "io/camfi/websocket.h"
#include "io/formats/atomic_file.h"
#include "io/sources/image_markers.h"

namespace flysfm {
namespace {

using Clock = std::chrono::steady_clock;

constexpr const char* kJournalName = "journal.tsv";
// Room below NAME_MAX (255) for "~<version>" and the ".tmp" of the write.
constexpr std::size_t kMaxStoreName = 200;

double SecondsSince(Clock::time_point t) {
  return std::chrono::duration<double>(Clock::now() - t).count();
}

std::string Lower(std::string text) {
  std::transform(text.begin(), text.end(), text.begin(),
                 [](unsigned char c) { return char(std::tolower(c)); });
  return text;
}

std::string Sha1Hex(const std::vector<std::uint8_t>& bytes) {
  unsigned char hash[20];
  websocketpp::sha1::calc(bytes.data(), bytes.size(), hash);
  static const char kHex[] = "0123456789abcdef";
  std::string hex;
  for (const unsigned char byte : hash) {
    hex.push_back(kHex[byte >> 4]);
    hex.push_back(kHex[byte & 0xF]);
  }
  return hex;
}

std::string Describe(const HttpResult& result) {
  return result.error.empty() ? "HTTP " + std::to_string(result.status) : result.error;
}

}  // namespace

bool CamfiOptions::Check(std::string* bad_option) const {
  const auto valid_port = [](int port) { return port > 0 && port < 65536; };
  const std::vector<std::pair<bool, const char*>> checks = {
      {!host.empty(), "host"},
      {valid_port(http_port), "http_port"},
      {valid_port(event_port), "event_port"},
      {reconcile_seconds > 0, "reconcile_seconds"},
      {list_page > 0, "list_page"},
      {max_list_pages > 0, "max_list_pages"},
      {retries > 0, "retries"},
      {control_timeout > 0, "control_timeout"},
      {list_timeout > 0, "list_timeout"},
      {download_idle_seconds > 0, "download_idle_seconds"},
      {download_total_seconds > 0, "download_total_seconds"},
      {max_shot_bytes > 0, "max_shot_bytes"},
      {max_body_bytes > 0, "max_body_bytes"},
      {max_event_message_bytes > 0, "max_event_message_bytes"},
      {max_json_depth > 0, "max_json_depth"},
      {backoff_min_seconds > 0, "backoff_min_seconds"},
      {backoff_max_seconds >= backoff_min_seconds, "backoff_max_seconds"},
      {ping_interval_override_ms >= 0, "ping_interval_override_ms"},
      {ping_timeout_override_ms >= 0, "ping_timeout_override_ms"},
      {!cache_route.empty(), "cache_route"},
      {engine_io_version == 3 || engine_io_version == 4, "engine_io_version"}};
  for (const auto& [valid, name] : checks) {
    if (!valid) {
      if (bad_option != nullptr) *bad_option = name;
      return false;
    }
  }
  return true;
}

std::string StoreNameForDevicePath(const std::string& device_path, int version) {
  std::string name = device_path;
  while (!name.empty() && name.front() == '/') name.erase(0, 1);
  for (char& c : name) {
    const auto byte = static_cast<unsigned char>(c);
    if (!(std::isalnum(byte) || c == '-' || c == '.' || c == '_')) c = '_';
  }
  // Never "", "." or "..", nor a hidden file.
  if (name.empty() || name.front() == '.') name.insert(0, "_");
  // The end keeps the file name and its extension.
  if (name.size() > kMaxStoreName) name.erase(0, name.size() - kMaxStoreName);
  if (version > 1) {
    const std::size_t dot = name.rfind('.');
    name.insert(dot == std::string::npos || dot == 0 ? name.size() : dot,
                "~" + std::to_string(version));
  }
  return name;
}

CamfiSource::CamfiSource(const CamfiOptions& options, const std::filesystem::path& store_dir)
    : options_(options),
      store_dir_(store_dir),
      http_(options.host, options.http_port, options.password) {
  std::string bad_option;
  if (!options_.Check(&bad_option)) {
    throw std::invalid_argument("invalid CAMFI option " + bad_option);
  }
  std::error_code error;
  std::filesystem::create_directories(store_dir_, error);
  if (error) {
    throw std::runtime_error("cannot create the image store " + store_dir_.string() + ": " +
                             error.message());
  }
  JournalContents contents;
  std::size_t torn_bytes = 0;
  journal_ = std::make_unique<CamfiJournalFile>(store_dir_ / kJournalName, options_.store_write_fault,
                                           &contents, &torn_bytes);
  if (torn_bytes > 0) {
    Log(std::string(kJournalName) + ": the last record was cut short by a crash (" +
        std::to_string(torn_bytes) + " bytes without a newline); dropped");
    stats_.journal_torn = 1;
  }
  for (const std::string& problem : contents.skipped) {
    Log(std::string(kJournalName) + " " + problem + "; record skipped");
  }
  stats_.journal_skipped = int(contents.skipped.size());
  Replay(contents);
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

// Runs before the threads start: no lock needed.
void CamfiSource::Replay(const JournalContents& contents) {
  for (const JournalRecord& record : contents.records) {
    if (record.kind == JournalRecord::Kind::kBaseline) {
      baseline_done_ = true;
    } else if (record.kind == JournalRecord::Kind::kIgnored) {
      ignored_.insert(record.device_path);
    } else {
      const std::filesystem::path file = store_dir_ / record.store_name;
      const std::vector<std::uint8_t> bytes = ReadFileBytes(file);
      const ShotId id{bytes.size(), Sha1Hex(bytes)};
      if (id.bytes != record.bytes || (!record.sha1.empty() && id.sha1 != record.sha1) ||
          !LooksCompleteImage(file, bytes)) {
        Log("journal names " + file.string() + " but the file is missing or damaged; "
            "it will be fetched again");
        retry_.insert(record.device_path);
        continue;
      }
      std::vector<ShotId>& versions = stored_[record.device_path];
      if (!store_names_.insert(record.store_name).second ||
          std::find(versions.begin(), versions.end(), id) != versions.end()) {
        continue;
      }
      versions.push_back(id);
      Frame frame;
      frame.name = record.store_name;
      frame.path = file;
      frame.timestamp = double(stored_paths_.size());
      frame.arrival = Clock::now();
      ready_.push_back(std::move(frame));
      stored_paths_.push_back(record.device_path);
      ++stats_.replayed;
    }
  }
  // Temporary files of writes a crash or a full disk interrupted.
  for (const auto& entry : std::filesystem::directory_iterator(store_dir_)) {
    if (entry.path().extension() == ".tmp") std::filesystem::remove(entry.path());
  }
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

void CamfiSource::Offer(const std::string& device_path, Trigger trigger,
                        Clock::time_point arrival) {
  const std::string extension = Lower(std::filesystem::path(device_path).extension().string());
  const bool wanted = std::find(options_.extensions.begin(), options_.extensions.end(),
                                extension) != options_.extensions.end() &&
                      std::find(options_.ignore_paths.begin(), options_.ignore_paths.end(),
                                device_path) == options_.ignore_paths.end();
  const bool from_event = trigger == Trigger::kEvent;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (from_event) ++stats_.events;
    if (!wanted) return;
    if (in_flight_.count(device_path) > 0) {
      if (from_event) ++stats_.duplicate_events;
      return;
    }
    const bool known = stored_.count(device_path) > 0 || ignored_.count(device_path) > 0 ||
                       too_large_.count(device_path) > 0;
    if (known && trigger == Trigger::kListed && retry_.count(device_path) == 0) return;
    if (known) {
      ++stats_.rechecked;
    } else if (!from_event) {
      ++stats_.found_by_listing;
    }
    retry_.erase(device_path);
    in_flight_.insert(device_path);
    queue_.push_back({device_path, arrival, from_event});
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
  const HttpLimits control{options_.control_timeout, 0, options_.max_body_bytes};
  const HttpResult info = http_.Get("/info", control, &stopping_);
  if (info.status == 404) {
    // Firmware older than /info (docs/camfi.md 1): version 1.0.0.0.
  } else if (info.status == 401) {
    throw std::runtime_error("the device asks for a password (--camfi-password)");
  } else if (info.status != 200) {
    throw std::runtime_error("no answer from " + options_.host + ":" +
                             std::to_string(options_.http_port) + "/info: " + Describe(info));
  }
  const HttpResult camera = http_.Get("/camera", control, &stopping_);
  if (camera.status == 200) {
    std::string problem;
    const std::optional<nlohmann::json> body =
        ParseBoundedJson(camera.BodyText(), options_.max_json_depth, &problem);
    if (!body || !body->is_object() || !body->contains("model") || !(*body)["model"].is_string() ||
        (*body)["model"].get<std::string>().empty()) {
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
  if (baseline && !Reconcile(/*baseline=*/true)) {
    throw std::runtime_error("no baseline listing of the card yet");
  }

  WebSocket socket = WebSocket::Connect(
      options_.host, options_.event_port, EngineIoResource(options_.engine_io_version),
      int(1000 * options_.control_timeout), options_.max_event_message_bytes);
  // A message the socket refused (over the bound, bad framing) is counted
  // before the session ends on it.
  const auto closed = [&] {
    if (!socket.error().empty()) {
      std::lock_guard<std::mutex> lock(mutex_);
      ++stats_.rejected_packets;
      return std::runtime_error("the event channel was dropped: " + socket.error());
    }
    return std::runtime_error("the event channel closed");
  };
  std::string packet;
  const WebSocket::Status first = socket.Receive(&packet, int(1000 * options_.control_timeout));
  if (first == WebSocket::Status::kClosed) throw closed();
  if (first != WebSocket::Status::kMessage) {
    throw std::runtime_error("the event channel sent no open packet");
  }
  const std::optional<EngineIoOpen> open = ParseEngineIoOpen(packet, options_.max_json_depth);
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
    const HttpResult tether = http_.Post("/tether/start", control);
    if (tether.status != 200) {
      Log("/tether/start failed (" + Describe(tether) +
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
    if (status == WebSocket::Status::kClosed) throw closed();
    if (status == WebSocket::Status::kMessage) {
      last_packet = Clock::now();
      if (packet == "1" || packet == "41") throw std::runtime_error("the device closed the session");
      if (packet == "2") socket.Send("3");
      const std::optional<SocketIoEvent> event =
          ParseSocketIoEvent(packet, options_.max_json_depth);
      if (!event && packet.compare(0, 2, "42") == 0) {
        Log("event packet of " + std::to_string(packet.size()) +
            " bytes ignored: not a [name, args...] array, or nested too deep");
        std::lock_guard<std::mutex> lock(mutex_);
        ++stats_.rejected_packets;
      } else if (event && event->name == "file_added" && !event->args.empty() &&
                 event->args[0].is_string()) {
        Offer(event->args[0].get<std::string>(), Trigger::kEvent, last_packet);
      } else if (event && event->name == "camera_add") {
        arm();
        Reconcile(/*baseline=*/false);
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

bool CamfiSource::Reconcile(bool baseline) {
  const HttpLimits limits{options_.list_timeout, 0, options_.max_body_bytes};
  FilesListing listing(options_.max_list_pages);
  // Only paths known before the listing began can be missing from it: a shot
  // stored meanwhile was not on the card when it was listed.
  std::set<std::string> known_before;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    known_before = ignored_;
    for (const auto& entry : stored_) known_before.insert(entry.first);
  }
  std::optional<std::vector<std::string>> page;
  do {
    const HttpResult answer = http_.Get(
        "/files/" + std::to_string(listing.next_start()) + "/" + std::to_string(options_.list_page),
        limits, &stopping_);
    std::string problem;
    if (answer.status != 200) {
      problem = Describe(answer);
    } else {
      page = ParseFilesPage(answer.BodyText(), options_.max_json_depth, &problem);
    }
    if (!problem.empty()) {
      if (stopping_) return false;
      Log("listing /files/" + std::to_string(listing.next_start()) + " failed (" + problem +
          "); listed again at the next reconcile");
      std::lock_guard<std::mutex> lock(mutex_);
      ++stats_.listing_failures;
      if (answer.too_large) ++stats_.oversized;
      return false;
    }
  } while (listing.Add(*page));
  if (listing.truncated()) {
    Log("listing stopped after " + std::to_string(options_.max_list_pages) +
        " pages (max_list_pages); the rest of the card is listed again next time");
    std::lock_guard<std::mutex> lock(mutex_);
    ++stats_.truncated_listings;
  }
  const std::vector<std::string>& paths = listing.paths();
  if (baseline) {
    std::lock_guard<std::mutex> lock(mutex_);
    std::string records;
    for (const std::string& path : paths) {
      if (stored_.count(path) == 0 && ignored_.count(path) == 0) {
        records += FormatJournalRecord(JournalRecord::Ignored(path));
      }
    }
    records += FormatJournalRecord(JournalRecord::Baseline());
    std::string error;
    if (!journal_->Append(records, &error)) {
      Log(error + "; the baseline is taken again");
      ++stats_.store_failures;
      return false;
    }
    ignored_.insert(paths.begin(), paths.end());
    baseline_done_ = true;
  } else {
    for (const std::string& path : paths) {
      Offer(path, vanished_.erase(path) > 0 ? Trigger::kReappeared : Trigger::kListed,
            Clock::now());
    }
  }
  // A truncated listing says nothing about the paths it did not reach.
  if (!listing.truncated()) {
    const std::set<std::string> listed(paths.begin(), paths.end());
    for (const std::string& path : known_before) {
      if (listed.count(path) == 0) vanished_.insert(path);
    }
  }
  return true;
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
    Fetch fetch = Fetch::kFailed;
    double retry_wait = 0.25;
    for (int attempt = 0; attempt < options_.retries && !stopping_; ++attempt) {
      fetch = Download(item.device_path, &bytes);
      if (fetch != Fetch::kFailed) break;
      if (!Wait(retry_wait)) break;
      retry_wait = std::min(2 * retry_wait, 4.0);
    }
    if (stopping_) return;
    const bool kept = fetch == Fetch::kOk && Keep(item, bytes);
    std::lock_guard<std::mutex> lock(mutex_);
    in_flight_.erase(item.device_path);
    if (fetch == Fetch::kTooLarge) {
      too_large_.insert(item.device_path);
    } else if (!kept) {
      if (fetch == Fetch::kFailed) {
        Log(item.device_path + " not fetched after " + std::to_string(options_.retries) +
            " attempts; retried after the next listing");
      }
      retry_.insert(item.device_path);
    }
  }
}

CamfiSource::Fetch CamfiSource::Download(const std::string& device_path,
                                         std::vector<std::uint8_t>* bytes) {
  const bool cached = !options_.cache_prefix.empty() &&
                      device_path.compare(0, options_.cache_prefix.size(),
                                          options_.cache_prefix) == 0;
  const std::string target =
      (cached ? options_.cache_route : std::string("/raw/")) + EncodeDevicePath(device_path);
  HttpResult result = http_.Get(
      target,
      {options_.download_total_seconds, options_.download_idle_seconds, options_.max_shot_bytes},
      &stopping_);
  std::string problem;
  if (!result.error.empty()) {
    problem = result.error;
    if (result.timed_out) {
      problem += " (bounds: " + std::to_string(options_.download_idle_seconds) + " s idle, " +
                 std::to_string(options_.download_total_seconds) + " s in all)";
    }
  } else if (result.status != 200) {
    problem = "HTTP " + std::to_string(result.status);
    std::string not_json;
    const std::optional<nlohmann::json> body =
        ParseBoundedJson(result.BodyText(), options_.max_json_depth, &not_json);
    if (body && body->is_object() && body->contains("message") && (*body)["message"].is_string()) {
      problem += " (" + (*body)["message"].get<std::string>() + ")";
    }
  } else if (result.content_length >= 0 &&
             result.body.size() != std::size_t(result.content_length)) {
    problem = std::to_string(result.body.size()) + " bytes of " +
              std::to_string(result.content_length);
  } else if (!HasJpegMarkers(result.body)) {
    problem = "not a complete JPEG (start/end markers missing)";
  }
  if (!problem.empty()) {
    if (stopping_) return Fetch::kFailed;
    Log("download of " + device_path + " rejected: " + problem +
        (result.too_large ? "; not asked for again unless it changes (max_shot_bytes)" : ""));
    std::lock_guard<std::mutex> lock(mutex_);
    ++stats_.download_failures;
    if (result.too_large) ++stats_.oversized;
    if (result.timed_out) ++stats_.timed_out_downloads;
    return result.too_large ? Fetch::kTooLarge : Fetch::kFailed;
  }
  *bytes = std::move(result.body);
  return Fetch::kOk;
}

std::string CamfiSource::FreeStoreNameLocked(const std::string& device_path) const {
  for (int version = 1;; ++version) {
    std::string name = StoreNameForDevicePath(device_path, version);
    // A file not in the journal (a shot a full disk kept from being
    // journalled, a user's file) is not overwritten either.
    if (store_names_.count(name) == 0 && !std::filesystem::exists(store_dir_ / name)) {
      return name;
    }
  }
}

bool CamfiSource::Keep(const Pending& item, const std::vector<std::uint8_t>& bytes) {
  const ShotId id{bytes.size(), Sha1Hex(bytes)};
  std::string name;
  bool reused = false;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    const auto found = stored_.find(item.device_path);
    if (found != stored_.end()) {
      if (std::find(found->second.begin(), found->second.end(), id) != found->second.end()) {
        if (item.from_event) ++stats_.duplicate_events;
        return true;
      }
      reused = true;
    }
    name = FreeStoreNameLocked(item.device_path);
    store_names_.insert(name);
  }
  const std::filesystem::path file = store_dir_ / name;
  // Takes back what was written and the name reserved.
  const auto undo = [&] {
    std::error_code ignored;
    std::filesystem::remove(file, ignored);
    std::lock_guard<std::mutex> lock(mutex_);
    store_names_.erase(name);
  };
  const auto fail = [&](const std::string& why) {
    Log("cannot store " + item.device_path + " (" + why +
        "); it stays to fetch and is fetched again at the next listing");
    undo();
    std::lock_guard<std::mutex> lock(mutex_);
    ++stats_.store_failures;
    return false;
  };
  try {
    WriteFileAtomically(
        file,
        [&](std::ostream& out) {
          const int fault = options_.store_write_fault ? options_.store_write_fault(file) : 0;
          const std::size_t size = fault != 0 ? bytes.size() / 2 : bytes.size();
          out.write(reinterpret_cast<const char*>(bytes.data()), std::streamsize(size));
          if (fault != 0) out.setstate(std::ios::badbit);
        },
        /*binary=*/true);
  } catch (const std::exception& e) {
    return fail(e.what());
  }
  {
    std::unique_lock<std::mutex> lock(mutex_);
    // Stopped meanwhile: Next() may have ended already, so the shot is left
    // for the next run to fetch rather than journalled and never processed.
    if (stopping_) {
      lock.unlock();
      undo();
      return true;
    }
    std::string error;
    if (!journal_->Append(FormatJournalRecord(
                              JournalRecord::Stored(item.device_path, name, bytes.size(), id.sha1)),
                          &error)) {
      lock.unlock();
      return fail(error);
    }
    Frame frame;
    frame.name = name;
    frame.path = file;
    frame.timestamp = double(stored_paths_.size());
    frame.arrival = item.arrival;
    ready_.push_back(std::move(frame));
    stored_paths_.push_back(item.device_path);
    stored_[item.device_path].push_back(id);
    ++stats_.stored;
    if (reused) ++stats_.reused_paths;
  }
  if (reused) {
    Log(item.device_path + " holds a new shot (card swapped or numbering restarted): stored as " +
        name);
  }
  wake_.notify_all();
  return true;
}

}  // namespace flysfm
