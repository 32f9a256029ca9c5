#pragma once

// A local stand-in for a CAMFI transmitter, for users without the hardware
// and for tests: the confirmed REST routes (docs/camfi.md 2.1) on one
// port, the Engine.IO v3 event channel (WebSocket transport) on another,
// both bound to 127.0.0.1 only. A folder of JPEGs is "shot" one by one onto a
// fake card under gphoto2-style paths (/store_00010001/DCIM/100CANON/
// IMG_0001.JPG), each announced by `file_added`. Seeded faults reproduce what
// a real link does: dropped socket, silent stall, duplicate, missing and
// out-of-order events, a truncated body, HTTP 500 right after an event,
// authentication, firmware without /info.

#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <filesystem>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <set>
#include <string>
#include <thread>
#include <vector>

namespace httplib {
class Server;
}

namespace flysfm {

enum class CamfiFault {
  kDropSocket,  // event channels closed just before the shot's event
  kStall,       // event channels go silent (no pong, no event), TCP stays up
  kDuplicate,   // the shot's event is sent twice
  kMissing,     // the shot's event is never sent
  kOutOfOrder,  // the shot's event is sent after the next shot's
  kTruncate,    // the first download of the shot stops half way
  kHttp500,     // the first download of the shot answers 500
  kAuth,        // every HTTP call needs user CamFi and the password
  kLegacyInfo,  // /info answers 404 (firmware 1.0.0.0)
  kTrickle,     // the first download of the shot sends one byte a second
};

// "drop-socket", "stall", "duplicate", "missing", "out-of-order",
// "truncate", "http500", "auth", "legacy-info", "trickle".
std::optional<CamfiFault> ParseCamfiFault(const std::string& name);
std::string CamfiFaultName(CamfiFault fault);
std::vector<std::string> CamfiFaultNames();

struct CamfiEmulatorOptions {
  // Shot in this order. Files that are not JPEG (a TUM sequence's PNGs) are
  // re-encoded as JPEG (quality 95), as a camera would have written them.
  std::vector<std::filesystem::path> images;
  // 0: an ephemeral port (read it back with http_port() / event_port()).
  int http_port = 80;
  int event_port = 8080;
  // Seconds between shots. The first shot comes one interval after the
  // first event client connects, so nothing is shot before anyone listens.
  double interval_seconds = 2;
  // Engine.IO protocol of the event channel: 3 (socket.io 1.x/2.x, as the
  // known CAMFI clients imply) or 4 (the server pings; the client sends "40").
  int engine_io_version = 3;
  // Engine.IO open packet (socket.io 1.x defaults).
  int ping_interval_ms = 25000;
  int ping_timeout_ms = 60000;
  std::set<CamfiFault> faults;
  // A per-shot fault hits every `fault_every`-th shot, from an offset drawn
  // from `seed`; the same seed gives the same faults.
  int fault_every = 3;
  std::uint32_t seed = 1;
  // Password of the `auth` fault (user "CamFi", HTTP Basic).
  std::string password = "camfi";
  // Reject /raw/ paths whose "/" are not encoded as %2F (HTTP 500).
  bool strict_path_encoding = true;
  // Card folder; "100CANON" rolls over to "101CANON" after this many files.
  std::string store = "/store_00010001";
  int folder_size = 9999;
  // /files quirks of other firmware: at most this many paths a page (0: as
  // many as asked), `start` ignored (every page from the first file), and
  // the first `files_failures` listings answered with
  // `files_failure_status` and `files_failure_body` (a busy camera).
  int files_page_limit = 0;
  bool files_ignore_start = false;
  int files_failures = 0;
  int files_failure_status = 500;
  std::string files_failure_body = R"({"message":"camera busy"})";

  bool Check() const;
};

struct CamfiEmulatorStats {
  int shots = 0;
  int events_sent = 0;  // file_added packets written to a client
  int sockets_dropped = 0;
  int sockets_stalled = 0;
  int events_duplicated = 0;
  int events_missing = 0;
  int events_reordered = 0;
  int bodies_truncated = 0;
  int http_500 = 0;
  int unauthorized = 0;
  int bodies_trickled = 0;
  int files_failed = 0;  // listings answered with the failure body
  int raw_served = 0;  // complete /raw/ downloads
};

class CamfiEmulator {
 public:
  // Binds both ports and starts serving. Throws std::invalid_argument for
  // bad options or unreadable images, std::runtime_error when a port is
  // taken.
  explicit CamfiEmulator(const CamfiEmulatorOptions& options);
  ~CamfiEmulator();

  int http_port() const { return http_port_; }
  int event_port() const { return event_port_; }
  // The device path of the `index`-th file (0-based) shot onto a card.
  std::string DevicePath(int index) const;
  // "METHOD target" of every HTTP request, target exactly as received.
  std::vector<std::string> RequestLog() const;
  CamfiEmulatorStats stats() const;
  int num_images() const { return int(images_.size()); }
  // Fires the next shot now (what GET /takepic/true does).
  void Shoot();
  // Swaps the card for an empty one: the next shots are numbered from
  // IMG_0001 again, under the paths of the first card, with new images.
  void SwapCard();
  // Sends `packet` as is on every event channel (hostile-firmware tests).
  void SendPacket(const std::string& packet);

 private:
  struct Connection;
  void SetUpRoutes();
  void AcceptLoop();
  void Serve(std::shared_ptr<Connection> connection, int fd);
  void DriveShots();
  // Puts the next image on the card; its shot index and path. mutex_ held.
  std::pair<int, std::string> PutOnCardLocked();
  // Puts the next image on the card and queues its event(s); mutex_ held.
  void FireLocked();
  void SendLocked(const std::vector<std::string>& events);
  bool Hits(CamfiFault fault, int shot) const;

  CamfiEmulatorOptions options_;
  std::vector<std::shared_ptr<const std::string>> images_;
  std::map<CamfiFault, int> fault_offsets_;
  std::unique_ptr<httplib::Server> server_;
  int http_port_ = 0;
  int event_port_ = 0;
  int listen_fd_ = -1;
  std::atomic<bool> stopping_{false};

  mutable std::mutex mutex_;
  std::condition_variable wake_;
  int next_shot_ = 0;
  // Files shot onto the current card.
  int card_files_ = 0;
  int files_failures_left_ = 0;
  bool client_seen_ = false;
  // POST /tether/start arms the events of shutter-button shots (docs/camfi.md 2.1).
  bool tethered_ = false;
  // Card path -> shot index of every file shot so far, in shot order.
  std::vector<std::string> card_;
  std::map<std::string, int> card_index_;
  // The download faults already served, per shot: each hits one download.
  std::set<std::pair<CamfiFault, int>> download_fault_used_;
  std::optional<std::string> held_event_;
  std::vector<std::shared_ptr<Connection>> connections_;
  std::vector<std::string> request_log_;
  CamfiEmulatorStats stats_;

  std::thread http_thread_;
  std::thread accept_thread_;
  std::thread shot_thread_;
  std::vector<std::thread> connection_threads_;
};

}  // namespace flysfm
