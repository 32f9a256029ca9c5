#pragma once

// Live images from a CAMFI WiFi transmitter (../shared/camfi.md): the REST
// port for probing, listing and downloading, the Engine.IO v3 event channel
// for `file_added`. A session runs
//   probe (/info, /camera) -> events open -> /tether/start -> reconcile
//   (/files) -> live (events, pings, periodic reconcile)
// and on any failure backs off and starts over, so a dropped link, a stale
// socket or a missed event never loses a shot: every path on the card not
// yet in the store is fetched at the next listing.
//
// The session's store is a folder: one file per shot, named from its full
// device path, plus journal.tsv. A shot is written (complete, checked) and
// journalled before Next() hands it on; a new source on the same store first
// hands on what the journal holds, in journal order, and never fetches those
// paths again.

#include <atomic>
#include <condition_variable>
#include <deque>
#include <filesystem>
#include <fstream>
#include <mutex>
#include <optional>
#include <set>
#include <string>
#include <thread>
#include <vector>

#include "io/camfi/camfi_http.h"
#include "io/sources/image_source.h"

namespace flysfm {

class WebSocket;

struct CamfiOptions {
  // AP-mode default address of the device (camfi.md 1).
  std::string host = "192.168.9.67";
  int http_port = 80;
  int event_port = 8080;
  // Access password; empty: none. Sent as user "CamFi".
  std::string password;
  // POST /tether/start on every (re)connect, so that shots taken with the
  // camera's own shutter button produce events.
  bool tether_on_connect = true;
  // List /files this often while live (seconds), besides after each connect.
  double reconcile_seconds = 10;
  // Page size of /files/<start>/<count>.
  int list_page = 100;
  // Files already on the card when a fresh store starts are ignored, unless
  // this is set (they are then fetched like new shots).
  bool fetch_existing = false;
  // Extensions (lower case) that are fetched; other files are skipped.
  std::vector<std::string> extensions = {".jpg", ".jpeg"};
  // Placeholder paths some firmware announces (camfi.md 3.3).
  std::vector<std::string> ignore_paths = {"/foo.jpg"};
  // Device paths under this prefix are served by `cache_route`, others by
  // /raw/ (camfi.md 2.2).
  std::string cache_prefix = "/tmp/sd/DCIM/";
  std::string cache_route = "/cache/image/";
  // Download attempts per shot before it waits for the next listing.
  int retries = 5;
  // Timeouts (seconds): control calls, listing, connecting the event
  // channel; downloads end only after `download_idle_seconds` without data.
  double control_timeout = 5;
  double list_timeout = 10;
  double download_idle_seconds = 15;
  // Reconnect back-off, doubling from min to max, with jitter.
  double backoff_min_seconds = 0.5;
  double backoff_max_seconds = 5;
  // Engine.IO protocol: 3 (socket.io 1.x/2.x; every known CAMFI client) or
  // 4 (server pings, client joins the namespace with "40"), for firmware
  // that may move on (camfi.md 3.1).
  int engine_io_version = 3;
  // Overrides the device's pingInterval / pingTimeout when > 0 (ms).
  int ping_interval_override_ms = 0;
  int ping_timeout_override_ms = 0;

  bool Check() const;
};

struct CamfiStats {
  int sessions = 0;          // event channels opened
  int session_failures = 0;  // sessions that ended in an error or a watchdog
  int events = 0;            // file_added received
  int duplicate_events = 0;  // file_added for a path already known
  int found_by_listing = 0;  // new paths found by /files, not by an event
  int download_failures = 0; // attempts rejected (HTTP error, cut, bad bytes)
  int stored = 0;            // shots written to the store this run
  int replayed = 0;          // shots handed on again from the journal
};

class CamfiSource : public ImageSource {
 public:
  // Opens (creating if needed) the store in `store_dir` and starts the
  // session and the download worker. Throws std::invalid_argument for bad
  // options, std::runtime_error for an unwritable store or journal.
  CamfiSource(const CamfiOptions& options, const std::filesystem::path& store_dir);
  ~CamfiSource() override;

  // The next stored shot (journal replay first); blocks. After Stop(), hands
  // on the shots already stored, then nullopt.
  std::optional<Frame> Next() override;
  // Thread-safe; a download in progress is abandoned (the shot stays on the
  // card and is fetched by the next run on this store).
  void Stop();

  CamfiStats stats() const;
  // Device paths in the store, in journal order.
  std::vector<std::string> StoredDevicePaths() const;

 private:
  void ReadJournal();
  void AppendJournal(const std::string& line);
  void SessionLoop();
  void RunSession();
  void Reconcile(bool baseline);
  // Queues `device_path` unless filtered or already known.
  void Offer(const std::string& device_path, bool from_event,
             std::chrono::steady_clock::time_point arrival);
  void DownloadLoop();
  bool Download(const std::string& device_path, std::vector<std::uint8_t>* bytes);
  void Store(const std::string& device_path, const std::vector<std::uint8_t>& bytes,
             std::chrono::steady_clock::time_point arrival);
  // Sleeps up to `seconds`; false when stopped meanwhile.
  bool Wait(double seconds);
  void Log(const std::string& message) const;

  const CamfiOptions options_;
  const std::filesystem::path store_dir_;
  const CamfiHttp http_;
  std::atomic<bool> stopping_{false};

  mutable std::mutex mutex_;
  std::condition_variable wake_;
  // Every path queued, downloading, stored or ignored: one download per path.
  std::set<std::string> known_;
  struct Pending {
    std::string device_path;
    std::chrono::steady_clock::time_point arrival;
  };
  std::deque<Pending> queue_;
  std::deque<Frame> ready_;
  std::vector<std::string> stored_paths_;
  bool baseline_done_ = false;
  CamfiStats stats_;
  std::ofstream journal_;

  std::thread session_thread_;
  std::thread download_thread_;
};

// The store's file name for a device path: the path without its leading
// "/", with "/" as "_" ("store_00010001_DCIM_100CANON_IMG_0001.JPG"), so two
// folders' IMG_0001.JPG never collide.
std::string StoreNameForDevicePath(const std::string& device_path);

}  // namespace flysfm
