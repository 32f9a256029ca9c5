#pragma once

// Live images from a CAMFI WiFi transmitter (docs/camfi.md): the REST
// port for probing, listing and downloading, the Engine.IO v3 event channel
// for `file_added`. A session runs
//   probe (/info, /camera) -> events open -> /tether/start -> reconcile
//   (/files) -> live (events, pings, periodic reconcile)
// and on any failure backs off and starts over, so a dropped link, a stale
// socket or a missed event never loses a shot: every path on the card not
// yet in the store is fetched at the next listing.
//
// The session's store is a folder: one file per shot, named from its full
// device path, plus journal.tsv (io/camfi/camfi_journal.h). A shot is written
// (complete, checked) and journalled before Next() hands it on; a new source
// on the same store first hands on what the journal holds, in journal order,
// and does not fetch those paths again unless they may hold a new shot.
//
// A shot is its device path and its bytes: a known path is fetched again when
// `file_added` names it or when it reappears in a listing after missing from
// the previous one (a swapped card, a camera whose numbering restarted), and
// bytes that differ from every shot stored under that path are a new shot,
// stored under a new name. Everything from the device is bounded (body
// sizes, download time, event message size, JSON depth); going over a bound
// is a logged, counted rejection.

#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <filesystem>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <set>
#include <string>
#include <thread>
#include <vector>

#include "io/camfi/bounded_json.h"
#include "io/camfi/camfi_http.h"
#include "io/camfi/camfi_journal.h"
#include "io/camfi/websocket_reader.h"
#include "io/sources/image_source.h"

namespace flysfm {

struct CamfiOptions {
  // AP-mode default address of the device (docs/camfi.md 1).
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
  // Pages of one listing at most: a device that never stops bringing new
  // paths must not keep the session listing forever (1000 pages of 100 is a
  // card of 100000 files).
  int max_list_pages = 1000;
  // Files already on the card when a fresh store starts are ignored, unless
  // this is set (they are then fetched like new shots).
  bool fetch_existing = false;
  // Extensions (lower case) that are fetched; other files are skipped.
  std::vector<std::string> extensions = {".jpg", ".jpeg"};
  // Placeholder paths some firmware announces (docs/camfi.md 3.3).
  std::vector<std::string> ignore_paths = {"/foo.jpg"};
  // Device paths under this prefix are served by `cache_route`, others by
  // /raw/ (docs/camfi.md 2.2).
  std::string cache_prefix = "/tmp/sd/DCIM/";
  std::string cache_route = "/cache/image/";
  // Download attempts per shot before it waits for the next listing.
  int retries = 5;
  // Timeouts (seconds): control calls, listing, connecting the event
  // channel; a download ends after `download_idle_seconds` without data or
  // `download_total_seconds` in all (a device trickling a byte a second).
  double control_timeout = 5;
  double list_timeout = 10;
  double download_idle_seconds = 15;
  double download_total_seconds = 300;
  // Largest shot fetched (a 100 MP RAW is about 200 MiB); a larger body is
  // rejected, and that path is not asked for again in this run unless an
  // event or a reappearance says it changed.
  std::uint64_t max_shot_bytes = std::uint64_t(512) << 20;
  // Largest listing page or control answer (a page of 100 paths is about
  // 6 KB).
  std::uint64_t max_body_bytes = std::uint64_t(8) << 20;
  // Largest event-channel message (its fragments together), and deepest JSON
  // accepted from the device (listings, Engine.IO / Socket.IO payloads).
  std::size_t max_event_message_bytes = kDefaultMaxWebSocketMessageBytes;
  int max_json_depth = kDefaultMaxJsonDepth;
  // Reconnect back-off, doubling from min to max, with jitter.
  double backoff_min_seconds = 0.5;
  double backoff_max_seconds = 5;
  // Engine.IO protocol: 3 (socket.io 1.x/2.x; every known CAMFI client) or
  // 4 (server pings, client joins the namespace with "40"), for firmware
  // that may move on (docs/camfi.md 3.1).
  int engine_io_version = 3;
  // Overrides the device's pingInterval / pingTimeout when > 0 (ms).
  int ping_interval_override_ms = 0;
  int ping_timeout_override_ms = 0;
  // Tests only: a full disk on demand (CamfiJournalFile::WriteFault), asked
  // before every write to the store, shot or journal record.
  CamfiJournalFile::WriteFault store_write_fault;

  // False when an option is out of range; `*bad_option` then names it.
  bool Check(std::string* bad_option = nullptr) const;
};

struct CamfiStats {
  int sessions = 0;          // event channels opened
  int session_failures = 0;  // sessions that ended in an error or a watchdog
  int events = 0;            // file_added received
  int duplicate_events = 0;  // file_added for a path being fetched, or for
                             // bytes already stored under its path
  int found_by_listing = 0;  // new paths found by /files, not by an event
  int download_failures = 0;  // attempts rejected (HTTP error, cut, bad bytes,
                              // over a bound)
  int stored = 0;            // shots written to the store this run
  int replayed = 0;          // shots handed on again from the journal
  int rechecked = 0;         // known paths fetched again to compare bytes
  int reused_paths = 0;      // new shots at a known path (card swap, numbering reset)
  int listing_failures = 0;  // listings that failed; retried at the next reconcile
  int truncated_listings = 0;   // listings stopped by max_list_pages
  int oversized = 0;            // bodies over max_shot_bytes / max_body_bytes
  int timed_out_downloads = 0;  // downloads over the idle or total time
  int rejected_packets = 0;     // event messages over the size bound, bad framing,
                                // malformed or too deep event packets
  int store_failures = 0;       // shots or records not written (disk full); the
                                // shot stays to fetch
  int journal_skipped = 0;      // malformed journal records skipped at start
  int journal_torn = 0;         // journals whose last record a crash cut short
};

class CamfiSource : public ImageSource {
 public:
  // Opens (creating if needed) the store in `store_dir` and starts the
  // session and the download worker. Throws std::invalid_argument naming a
  // bad option, std::runtime_error for an unwritable store or journal.
  CamfiSource(const CamfiOptions& options, const std::filesystem::path& store_dir);
  ~CamfiSource() override;

  // The next stored shot (journal replay first); blocks. After Stop(), hands
  // on the shots already stored, then nullopt.
  std::optional<Frame> Next() override;
  // Thread-safe; a download in progress is abandoned (the shot stays on the
  // card and is fetched by the next run on this store).
  void Stop() override;

  CamfiStats stats() const;
  // Device paths in the store, in journal order (a reused path once per shot).
  std::vector<std::string> StoredDevicePaths() const;

 private:
  // How a path came to be offered.
  enum class Trigger {
    kEvent,       // file_added
    kListed,      // in a listing
    kReappeared,  // in a listing, after a complete one did not show it
  };
  enum class Fetch { kOk, kFailed, kTooLarge };
  struct ShotId {
    std::uint64_t bytes = 0;
    std::string sha1;
    bool operator==(const ShotId& other) const {
      return bytes == other.bytes && sha1 == other.sha1;
    }
  };
  struct Pending {
    std::string device_path;
    std::chrono::steady_clock::time_point arrival;
    bool from_event = false;
  };

  void Replay(const JournalContents& contents);
  void SessionLoop();
  void RunSession();
  // One listing; false (logged, counted) when it failed.
  bool Reconcile(bool baseline);
  // Queues `device_path` unless filtered, being fetched, or known and
  // merely listed again.
  void Offer(const std::string& device_path, Trigger trigger,
             std::chrono::steady_clock::time_point arrival);
  void DownloadLoop();
  Fetch Download(const std::string& device_path, std::vector<std::uint8_t>* bytes);
  // Stores the bytes as a shot unless they are a shot already stored under
  // that path; false (logged, counted) when the store could not be written.
  bool Keep(const Pending& item, const std::vector<std::uint8_t>& bytes);
  // A store name for `device_path` no stored shot uses; mutex_ held.
  std::string FreeStoreNameLocked(const std::string& device_path) const;
  // Sleeps up to `seconds`; false when stopped meanwhile.
  bool Wait(double seconds);
  void Log(const std::string& message) const;

  const CamfiOptions options_;
  const std::filesystem::path store_dir_;
  const CamfiHttp http_;
  std::atomic<bool> stopping_{false};

  mutable std::mutex mutex_;
  std::condition_variable wake_;
  // Paths queued or downloading: one download per path at a time.
  std::set<std::string> in_flight_;
  // The shots stored under each path; a path's bytes are compared with them.
  std::map<std::string, std::vector<ShotId>> stored_;
  std::set<std::string> store_names_;
  // On the card before the session began.
  std::set<std::string> ignored_;
  // Over max_shot_bytes: not asked for again when merely listed.
  std::set<std::string> too_large_;
  // Known paths whose fetch or store failed: fetched at the next listing.
  std::set<std::string> retry_;
  std::deque<Pending> queue_;
  std::deque<Frame> ready_;
  std::vector<std::string> stored_paths_;
  bool baseline_done_ = false;
  CamfiStats stats_;
  std::unique_ptr<CamfiJournalFile> journal_;
  // Known paths a complete listing did not show (session thread only): one
  // that shows again may hold a new shot.
  std::set<std::string> vanished_;

  std::thread session_thread_;
  std::thread download_thread_;
};

// The store's file name for a device path: the path without its leading
// "/", every byte outside [A-Za-z0-9._-] as "_"
// ("store_00010001_DCIM_100CANON_IMG_0001.JPG"), so two folders'
// IMG_0001.JPG never collide. The `version`-th shot (from 2) under the same
// path gets "~<version>" before the extension
// ("store_00010001_DCIM_100CANON_IMG_0001~2.JPG"), a name no path maps to.
std::string StoreNameForDevicePath(const std::string& device_path, int version = 1);

}  // namespace flysfm
