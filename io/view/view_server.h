#pragma once

// The live web view's HTTP server: the page, the system's three.js, the
// latest shot and the waiting and rejected shots as thumbnails, and the model
// pushed as server-sent events
// (docs/view.md). The engine thread publishes; HTTP worker threads serve.
// Publishing never waits for a browser: it applies the update to the view's
// own copy of the model and appends one shared message to each client's
// bounded queue. A client whose queue overflows gets the whole model again
// instead of what it missed (latest state wins).

#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <list>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <thread>

#include <opencv2/core.hpp>

#include "io/view/view_model.h"

namespace httplib {
class Server;
}

namespace flysfm {

struct ViewServerOptions {
  // 127.0.0.1: only this machine. With `lan`, 0.0.0.0 (a tablet on the same
  // WiFi) and every request must carry ?token=<token>.
  bool lan = false;
  int port = 8090;  // 0: any free port (tests)
  // The LAN token; empty: 128 random bits, in hex.
  std::string token;
  // Event streams served at once; each holds an HTTP worker thread.
  int max_clients = 8;
  // Messages waiting for one client before its queue is replaced by the
  // whole model.
  int max_queued_messages = 64;
  // A comment is sent to an idle stream this often, so that a vanished
  // browser is noticed and its worker freed.
  double keepalive_seconds = 5.0;
  // A browser that takes no bytes for this long is dropped.
  double write_timeout_seconds = 5.0;
  int thumbnail_width = 320;
  // Thumbnails kept of shots in the pending and rejected lists (about 20 KB
  // each at the width above); past this the oldest go, and the page lists
  // those shots without a picture.
  int max_list_thumbnails = 256;
  // Debian's libjs-three (r111): the library and its orbit controls.
  std::string three_js = "/usr/share/javascript/three/three.min.js";
  std::string orbit_controls_js =
      "/usr/share/javascript/three/examples/js/controls/OrbitControls.js";

  // Throws std::invalid_argument naming the bad option.
  void Check() const;
};

class ViewServer {
 public:
  // Reads three.js and binds; throws std::runtime_error with the reason (a
  // missing libjs-three, a port in use).
  explicit ViewServer(const ViewServerOptions& options);
  ~ViewServer();
  ViewServer(const ViewServer&) = delete;
  ViewServer& operator=(const ViewServer&) = delete;

  int port() const { return port_; }
  const std::string& token() const { return token_; }
  // The address to open, token included on the LAN (with this machine's
  // name standing for its address).
  std::string Url() const;

  // Engine thread. Cost: the update's size, plus a copy of pointers per
  // client; never a wait on a browser.
  void Publish(const ViewUpdate& update);
  // The latest shot (BGR) and its name; kept by reference, shrunk only when
  // asked for. An empty image (a shot that could not be decoded) is ignored.
  // The shot it replaces keeps a thumbnail if it is then pending or
  // rejected (a shrink on this thread, for those shots only), so that the
  // page can show what failed.
  void SetLatestShot(const cv::Mat& image, const std::string& name = "");
  // What a long step of the run is doing (the terminal's progress line),
  // shown on the page until the next status or the end; a page opened
  // meanwhile gets it with the model.
  void SetStatus(const std::string& text);
  // The run is over: every client gets `end` after what it has. Waits up to
  // `drain_seconds` for the open pages to receive it, so that a batch run
  // that exits right after does not cut them off.
  void Finish(double drain_seconds = 2.0);

  // Event streams open now.
  int num_clients() const;

 private:
  struct Client {
    std::list<std::shared_ptr<const std::string>> queue;
    bool needs_model = true;
    bool delivered_end = false;
  };
  // The next bytes for `client`, waiting up to the keep-alive; empty when
  // the server stops. `ends`: they close the stream (the run's `end`).
  std::string NextChunk(const std::shared_ptr<Client>& client, bool* ends);
  // The latest shot's; `name`, when given, receives that shot's name.
  std::string Thumbnail(std::string* name = nullptr);
  // The thumbnail of a pending or rejected shot, or of the latest; empty
  // when none is kept.
  std::string NamedThumbnail(const std::string& name);
  // Drops the kept thumbnails of shots no longer pending or rejected. With
  // mutex_ held.
  void PruneListThumbnails();

  ViewServerOptions options_;
  std::string token_;
  std::string three_js_;
  std::string orbit_controls_js_;
  std::unique_ptr<httplib::Server> http_;
  int port_ = 0;
  std::thread thread_;
  std::atomic<bool> listen_returned_{false};

  mutable std::mutex mutex_;
  std::condition_variable wake_;
  bool stopping_ = false;
  ViewModel model_;
  std::string status_;
  std::list<std::shared_ptr<Client>> clients_;

  std::mutex shot_mutex_;
  cv::Mat shot_;
  std::uint64_t shot_sequence_ = 0;
  std::string shot_name_;
  std::uint64_t thumbnail_sequence_ = 0;
  std::string thumbnail_;
  // Name -> JPEG, and the names in the order they were kept.
  std::map<std::string, std::string> list_thumbnails_;
  std::deque<std::string> list_thumbnail_order_;
};

}  // namespace flysfm
