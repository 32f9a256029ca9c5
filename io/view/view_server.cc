#include "io/view/view_server.h"

#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <chrono>
#include <fstream>
#include <random>
#include <sstream>
#include <stdexcept>

#include <httplib.h>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "io/view/view_www.h"

namespace flysfm {
namespace {

std::string ReadWholeFile(const std::string& path, const char* what) {
  std::ifstream in(path, std::ios::binary);
  if (!in) {
    throw std::runtime_error(std::string("the live view needs ") + what + " at " + path +
                             " (Debian package libjs-three; scripts/setup.sh installs it)");
  }
  std::ostringstream text;
  text << in.rdbuf();
  return text.str();
}

std::string RandomToken() {
  std::random_device device;
  static const char kHex[] = "0123456789abcdef";
  std::string token;
  for (int i = 0; i < 8; ++i) {
    const unsigned value = device();
    for (int nibble = 0; nibble < 4; ++nibble) token += kHex[(value >> (4 * nibble)) & 0xf];
  }
  return token;
}

// Compares in time independent of where the strings differ, so that a LAN
// guesser learns nothing from how fast a wrong token is refused.
bool SameToken(const std::string& a, const std::string& b) {
  if (a.size() != b.size()) return false;
  unsigned char difference = 0;
  for (std::size_t i = 0; i < a.size(); ++i) difference |= a[i] ^ b[i];
  return difference == 0;
}

std::string EventChunk(const std::string& message) { return "data: " + message + "\n\n"; }

// `image` at most `width` wide, as a JPEG; empty when it cannot be encoded.
std::string ShrinkToJpeg(const cv::Mat& image, int width) {
  cv::Mat small = image;
  if (image.cols > width) {
    const int height = std::max(1, int(std::lround(double(image.rows) * width / image.cols)));
    cv::resize(image, small, cv::Size(width, height), 0, 0, cv::INTER_AREA);
  }
  std::vector<std::uint8_t> jpeg;
  if (!cv::imencode(".jpg", small, jpeg, {cv::IMWRITE_JPEG_QUALITY, 80})) return "";
  return std::string(jpeg.begin(), jpeg.end());
}

}  // namespace

void ViewServerOptions::Check() const {
  if (port < 0 || port > 65535) {
    throw std::invalid_argument("view port must be 0..65535, not " + std::to_string(port));
  }
  if (max_clients < 1) throw std::invalid_argument("view max_clients must be at least 1");
  if (max_queued_messages < 1) {
    throw std::invalid_argument("view max_queued_messages must be at least 1");
  }
  if (!(keepalive_seconds > 0) || !(write_timeout_seconds > 0)) {
    throw std::invalid_argument("view keep-alive and write timeout must be positive");
  }
  if (thumbnail_width < 16) throw std::invalid_argument("view thumbnail_width must be >= 16");
  if (max_list_thumbnails < 0) {
    throw std::invalid_argument("view max_list_thumbnails must not be negative");
  }
  for (const char c : token) {
    if (!std::isalnum(static_cast<unsigned char>(c))) {
      throw std::invalid_argument("the view token may hold letters and digits only");
    }
  }
}

ViewServer::ViewServer(const ViewServerOptions& options) : options_(options) {
  options_.Check();
  three_js_ = ReadWholeFile(options_.three_js, "three.js");
  orbit_controls_js_ = ReadWholeFile(options_.orbit_controls_js, "three.js's OrbitControls");
  token_ = options_.lan ? (options_.token.empty() ? RandomToken() : options_.token) : "";

  http_ = std::make_unique<httplib::Server>();
  // One worker per event stream plus a few for the page's other requests.
  const std::size_t workers = std::size_t(options_.max_clients) + 4;
  http_->new_task_queue = [workers] { return new httplib::ThreadPool(workers); };
  const auto write_timeout = std::chrono::duration<double>(options_.write_timeout_seconds);
  http_->set_write_timeout(std::chrono::duration_cast<std::chrono::microseconds>(write_timeout));
  http_->set_read_timeout(5, 0);
  http_->set_payload_max_length(64 * 1024);  // the view takes no uploads
  http_->set_keep_alive_timeout(2);

  http_->set_pre_routing_handler([this](const httplib::Request& request,
                                        httplib::Response& response) {
    if (token_.empty()) return httplib::Server::HandlerResponse::Unhandled;
    if (request.has_param("token") && SameToken(request.get_param_value("token"), token_)) {
      return httplib::Server::HandlerResponse::Unhandled;
    }
    response.status = 403;
    response.set_content("forbidden: this view needs ?token=<the token flysfm printed>\n",
                         "text/plain");
    return httplib::Server::HandlerResponse::Handled;
  });
  const auto serve_text = [this](const char* path, const std::string* body, const char* type) {
    http_->Get(path, [body, type](const httplib::Request&, httplib::Response& response) {
      response.set_header("Cache-Control", "no-cache");
      response.set_content(*body, type);
    });
  };
  static const std::string index_html = kViewIndexHtml;
  static const std::string view_js = kViewJs;
  serve_text("/", &index_html, "text/html; charset=utf-8");
  serve_text("/view.js", &view_js, "application/javascript; charset=utf-8");
  serve_text("/three.js", &three_js_, "application/javascript; charset=utf-8");
  serve_text("/orbit.js", &orbit_controls_js_, "application/javascript; charset=utf-8");
  // Browsers ask for it on their own; a 404 would be an error in the console.
  http_->Get("/favicon.ico", [](const httplib::Request&, httplib::Response& response) {
    response.status = 204;
  });
  // ?name=<shot>: a pending or rejected shot's; else the latest.
  http_->Get("/thumbnail.jpg", [this](const httplib::Request& request,
                                      httplib::Response& response) {
    const bool named = request.has_param("name");
    const std::string jpeg = named ? NamedThumbnail(request.get_param_value("name")) : Thumbnail();
    response.set_header("Cache-Control", "no-store");
    if (jpeg.empty()) {
      response.status = 404;
      response.set_content(named ? "no thumbnail of that shot\n" : "no shot yet\n", "text/plain");
      return;
    }
    response.set_content(jpeg, "image/jpeg");
  });
  http_->Get("/events", [this](const httplib::Request&, httplib::Response& response) {
    auto client = std::make_shared<Client>();
    {
      std::lock_guard<std::mutex> lock(mutex_);
      if (int(clients_.size()) >= options_.max_clients) {
        response.status = 503;
        response.set_content("too many open views; close one\n", "text/plain");
        return;
      }
      clients_.push_back(client);
    }
    response.set_header("Cache-Control", "no-cache");
    response.set_header("X-Accel-Buffering", "no");
    response.set_chunked_content_provider(
        "text/event-stream",
        [this, client](std::size_t, httplib::DataSink& sink) {
          bool ends = false;
          const std::string chunk = NextChunk(client, &ends);
          if (chunk.empty()) return false;  // stopping
          if (!sink.write(chunk.data(), chunk.size())) return false;
          if (ends) {
            {
              std::lock_guard<std::mutex> lock(mutex_);
              client->delivered_end = true;
            }
            wake_.notify_all();
            sink.done();
          }
          return true;
        },
        [this, client](bool) {
          {
            std::lock_guard<std::mutex> lock(mutex_);
            clients_.remove(client);
          }
          wake_.notify_all();
        });
  });
  http_->set_error_handler([](const httplib::Request&, httplib::Response& response) {
    if (response.body.empty()) {
      response.set_content("error " + std::to_string(response.status) + "\n", "text/plain");
    }
  });

  const std::string host = options_.lan ? "0.0.0.0" : "127.0.0.1";
  if (options_.port == 0) {
    port_ = http_->bind_to_any_port(host);
    if (port_ <= 0) throw std::runtime_error("the live view cannot listen on " + host);
  } else {
    if (!http_->bind_to_port(host, options_.port)) {
      throw std::runtime_error("the live view cannot listen on " + host + ":" +
                               std::to_string(options_.port) + " (port in use?)");
    }
    port_ = options_.port;
  }
  thread_ = std::thread([this] {
    http_->listen_after_bind();
    listen_returned_ = true;
  });
  // httplib's stop() does nothing before the server runs: a server destroyed
  // right after it was made would otherwise listen for ever.
  while (!http_->is_running() && !listen_returned_) {
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
}

ViewServer::~ViewServer() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stopping_ = true;
  }
  wake_.notify_all();
  http_->stop();
  if (thread_.joinable()) thread_.join();
}

std::string ViewServer::Url() const {
  if (token_.empty()) return "http://127.0.0.1:" + std::to_string(port_) + "/";
  char host[256] = "localhost";
  ::gethostname(host, sizeof(host) - 1);
  return "http://" + std::string(host) + ":" + std::to_string(port_) + "/?token=" + token_;
}

void ViewServer::Publish(const ViewUpdate& update) {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    const bool lists_changed = model_.Apply(update);
    if (lists_changed) PruneListThumbnails();
    const auto message = std::make_shared<const std::string>(
        EventChunk(UpdateMessage(update, lists_changed ? &model_.snapshot() : nullptr)));
    for (const std::shared_ptr<Client>& client : clients_) {
      // A client about to get the whole model gets this update with it.
      if (client->needs_model) continue;
      if (int(client->queue.size()) >= options_.max_queued_messages) {
        client->queue.clear();
        client->needs_model = true;
        continue;
      }
      client->queue.push_back(message);
    }
  }
  wake_.notify_all();
}

void ViewServer::SetLatestShot(const cv::Mat& image, const std::string& name) {
  // An image that could not be decoded keeps the previous shot on show.
  if (image.empty()) return;
  cv::Mat previous;
  std::string previous_name;
  std::string previous_thumbnail;
  {
    std::lock_guard<std::mutex> lock(shot_mutex_);
    previous = shot_;
    previous_name = shot_name_;
    if (thumbnail_sequence_ == shot_sequence_) previous_thumbnail = thumbnail_;
    shot_ = image;
    shot_name_ = name;
    ++shot_sequence_;
  }
  if (previous_name.empty() || options_.max_list_thumbnails == 0) return;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    const ViewSnapshot& lists = model_.snapshot();
    if (!lists.pending.count(previous_name) && !lists.rejected.count(previous_name)) return;
  }
  if (previous_thumbnail.empty()) {
    previous_thumbnail = ShrinkToJpeg(previous, options_.thumbnail_width);
  }
  if (previous_thumbnail.empty()) return;
  std::lock_guard<std::mutex> lock(shot_mutex_);
  if (list_thumbnails_.count(previous_name)) return;
  list_thumbnails_[previous_name] = std::move(previous_thumbnail);
  list_thumbnail_order_.push_back(previous_name);
  while (int(list_thumbnail_order_.size()) > options_.max_list_thumbnails) {
    list_thumbnails_.erase(list_thumbnail_order_.front());
    list_thumbnail_order_.pop_front();
  }
}

void ViewServer::PruneListThumbnails() {
  const ViewSnapshot& lists = model_.snapshot();
  std::lock_guard<std::mutex> lock(shot_mutex_);
  std::deque<std::string> kept;
  for (const std::string& name : list_thumbnail_order_) {
    if (lists.pending.count(name) || lists.rejected.count(name)) {
      kept.push_back(name);
    } else {
      list_thumbnails_.erase(name);
    }
  }
  list_thumbnail_order_ = std::move(kept);
}

void ViewServer::SetStatus(const std::string& text) {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    status_ = text;
    const auto message = std::make_shared<const std::string>(EventChunk(StatusMessage(text)));
    for (const std::shared_ptr<Client>& client : clients_) {
      if (client->needs_model || int(client->queue.size()) >= options_.max_queued_messages) {
        continue;
      }
      client->queue.push_back(message);
    }
  }
  wake_.notify_all();
}

void ViewServer::Finish(double drain_seconds) {
  std::unique_lock<std::mutex> lock(mutex_);
  model_.Finish();
  const auto end = std::make_shared<const std::string>(EventChunk(EndMessage()));
  for (const std::shared_ptr<Client>& client : clients_) {
    // Beyond the bound: `end` is never the message that is dropped.
    if (!client->needs_model) client->queue.push_back(end);
  }
  wake_.notify_all();
  wake_.wait_for(lock, std::chrono::duration<double>(drain_seconds), [this] {
    return std::all_of(clients_.begin(), clients_.end(),
                       [](const std::shared_ptr<Client>& c) { return c->delivered_end; });
  });
}

int ViewServer::num_clients() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return int(clients_.size());
}

std::string ViewServer::NextChunk(const std::shared_ptr<Client>& client, bool* ends) {
  std::unique_lock<std::mutex> lock(mutex_);
  wake_.wait_for(lock, std::chrono::duration<double>(options_.keepalive_seconds), [&] {
    return stopping_ || client->needs_model || !client->queue.empty();
  });
  if (stopping_) return "";
  if (client->needs_model) {
    client->needs_model = false;
    client->queue.clear();
    // Flat arrays copied under the lock, written out without it.
    const ViewSnapshot snapshot = model_.snapshot();
    const std::string status = status_;
    lock.unlock();
    std::string chunk = "retry: 1000\n" + EventChunk(ModelMessage(snapshot));
    if (!snapshot.finished && !status.empty()) chunk += EventChunk(StatusMessage(status));
    if (snapshot.finished) {
      chunk += EventChunk(EndMessage());
      *ends = true;
    }
    return chunk;
  }
  const std::list<std::shared_ptr<const std::string>> queue = std::move(client->queue);
  client->queue.clear();
  const bool finished = model_.snapshot().finished;
  lock.unlock();
  if (queue.empty()) return ": keep-alive\n\n";
  std::string chunk;
  for (const auto& message : queue) chunk += *message;
  // `end` is queued last, once the run is finished.
  *ends = finished;
  return chunk;
}

std::string ViewServer::Thumbnail(std::string* name) {
  cv::Mat shot;
  std::uint64_t sequence = 0;
  {
    std::lock_guard<std::mutex> lock(shot_mutex_);
    if (name) *name = shot_name_;
    if (shot_.empty()) return "";
    if (thumbnail_sequence_ == shot_sequence_) return thumbnail_;
    shot = shot_;
    sequence = shot_sequence_;
  }
  std::string jpeg = ShrinkToJpeg(shot, options_.thumbnail_width);
  if (jpeg.empty()) return "";
  std::lock_guard<std::mutex> lock(shot_mutex_);
  if (sequence == shot_sequence_) {
    thumbnail_ = jpeg;
    thumbnail_sequence_ = sequence;
  }
  return jpeg;
}

std::string ViewServer::NamedThumbnail(const std::string& name) {
  {
    std::lock_guard<std::mutex> lock(shot_mutex_);
    const auto kept = list_thumbnails_.find(name);
    if (kept != list_thumbnails_.end()) return kept->second;
    if (name.empty() || name != shot_name_) return "";
  }
  // The latest may have changed meanwhile: only its own picture answers.
  std::string latest_name;
  std::string jpeg = Thumbnail(&latest_name);
  return latest_name == name ? jpeg : "";
}

}  // namespace flysfm
