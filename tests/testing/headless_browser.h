#pragma once

// A real browser for the tests of the live view: Debian's chromium, headless,
// driven over the Chrome DevTools Protocol with the project's own WebSocket
// client (io/camfi/websocket.h). One page; its console errors and uncaught
// exceptions are collected while any call waits.

#include <sys/types.h>

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "io/camfi/websocket.h"

namespace flysfm::testing {

// The chromium program on PATH (chromium, chromium-browser), if any.
std::optional<std::filesystem::path> FindChromium();

class HeadlessBrowser {
 public:
  // Starts chromium with a fresh profile in `profile_dir` (its output goes to
  // profile_dir/chromium.log) and opens one blank page. Throws
  // std::runtime_error saying what failed (no DevToolsActivePort within
  // `timeout_seconds`, a refused connection).
  HeadlessBrowser(const std::filesystem::path& chromium, const std::filesystem::path& profile_dir,
                  double timeout_seconds = 30);
  ~HeadlessBrowser();
  HeadlessBrowser(const HeadlessBrowser&) = delete;
  HeadlessBrowser& operator=(const HeadlessBrowser&) = delete;

  void Navigate(const std::string& url);
  // The expression's value (returnByValue; a Promise is awaited). Throws
  // std::runtime_error with the page's exception text when it throws.
  nlohmann::json Evaluate(const std::string& expression);
  // Polls `expression` every 100 ms until it is true; false on timeout.
  bool WaitFor(const std::string& expression, double timeout_seconds);
  void Screenshot(const std::filesystem::path& png);
  // Console errors (console.error / assert), uncaught exceptions, and
  // error entries of the browser's log (a failed resource load), so far.
  const std::vector<std::string>& errors() const { return errors_; }

 private:
  // Sends one command to the page's session (or the browser's, when
  // `browser_level`) and returns its result, handling events meanwhile.
  nlohmann::json Call(const std::string& method, const nlohmann::json& params,
                      bool browser_level = false);
  void OnEvent(const nlohmann::json& message);

  pid_t pid_ = -1;
  double timeout_seconds_;
  WebSocket socket_;
  std::string session_id_;
  int next_id_ = 1;
  std::vector<std::string> errors_;
};

}  // namespace flysfm::testing
