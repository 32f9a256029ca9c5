#include "tests/testing/headless_browser.h"

#include <fcntl.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdlib>
#include <fstream>
#include <sstream>
#include <stdexcept>
#include <thread>

namespace flysfm::testing {
namespace {

using Clock = std::chrono::steady_clock;

std::string DecodeBase64(const std::string& text) {
  std::string out;
  unsigned buffer = 0;
  int bits = 0;
  for (const char c : text) {
    int value;
    if (c >= 'A' && c <= 'Z') value = c - 'A';
    else if (c >= 'a' && c <= 'z') value = c - 'a' + 26;
    else if (c >= '0' && c <= '9') value = c - '0' + 52;
    else if (c == '+') value = 62;
    else if (c == '/') value = 63;
    else continue;  // padding, line breaks
    buffer = (buffer << 6) | unsigned(value);
    bits += 6;
    if (bits >= 8) {
      bits -= 8;
      out += char((buffer >> bits) & 0xff);
    }
  }
  return out;
}

std::string RemoteObjectText(const nlohmann::json& object) {
  if (object.contains("value")) {
    return object["value"].is_string() ? object["value"].get<std::string>()
                                       : object["value"].dump();
  }
  if (object.contains("description")) return object["description"].get<std::string>();
  return object.value("type", std::string("?"));
}

}  // namespace

std::optional<std::filesystem::path> FindChromium() {
  const char* path = std::getenv("PATH");
  std::stringstream folders(path ? path : "/usr/bin:/bin");
  for (std::string folder; std::getline(folders, folder, ':');) {
    for (const char* name : {"chromium", "chromium-browser"}) {
      const std::filesystem::path candidate = std::filesystem::path(folder) / name;
      if (::access(candidate.c_str(), X_OK) == 0) return candidate;
    }
  }
  return std::nullopt;
}

HeadlessBrowser::HeadlessBrowser(const std::filesystem::path& chromium,
                                 const std::filesystem::path& profile_dir,
                                 double timeout_seconds)
    : timeout_seconds_(timeout_seconds) {
  std::filesystem::create_directories(profile_dir);
  const std::filesystem::path port_file = profile_dir / "DevToolsActivePort";
  std::filesystem::remove(port_file);
  std::vector<std::string> args = {
      chromium.string(),
      "--headless=new",
      "--remote-debugging-port=0",
      "--user-data-dir=" + profile_dir.string(),
      "--no-sandbox",
      "--disable-gpu",
      // WebGL on the CPU: the software rasteriser must be asked for now.
      "--use-angle=swiftshader",
      "--enable-unsafe-swiftshader",
      "--no-first-run",
      "--no-default-browser-check",
      "--disable-dev-shm-usage",
      "--window-size=1280,800",
      "about:blank"};
  std::vector<char*> argv;
  for (std::string& arg : args) argv.push_back(arg.data());
  argv.push_back(nullptr);
  const std::string log = (profile_dir / "chromium.log").string();
  pid_ = ::fork();
  if (pid_ < 0) throw std::runtime_error("cannot fork for chromium");
  if (pid_ == 0) {
    // Its own process group, so that the destructor ends its helpers too.
    ::setpgid(0, 0);
    const int fd = ::open(log.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    ::dup2(fd, 1);
    ::dup2(fd, 2);
    ::execv(argv[0], argv.data());
    ::_exit(127);
  }

  // Chromium writes the port it chose, then the browser target's path.
  const auto deadline = Clock::now() + std::chrono::duration<double>(timeout_seconds);
  int port = 0;
  std::string browser_path;
  while (Clock::now() < deadline) {
    std::ifstream in(port_file);
    if (in >> port >> browser_path && port > 0 && !browser_path.empty()) break;
    port = 0;
    int status = 0;
    if (::waitpid(pid_, &status, WNOHANG) == pid_) {
      pid_ = -1;
      throw std::runtime_error("chromium exited at start (see " + log + ")");
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  if (port == 0) {
    throw std::runtime_error("chromium wrote no DevToolsActivePort within " +
                             std::to_string(timeout_seconds) + " s (see " + log + ")");
  }
  socket_ = WebSocket::Connect("127.0.0.1", port, browser_path, int(1000 * timeout_seconds),
                               std::size_t(256) << 20);
  const nlohmann::json target =
      Call("Target.createTarget", {{"url", "about:blank"}}, /*browser_level=*/true);
  const nlohmann::json attached =
      Call("Target.attachToTarget", {{"targetId", target["targetId"]}, {"flatten", true}},
           /*browser_level=*/true);
  session_id_ = attached["sessionId"].get<std::string>();
  Call("Runtime.enable", nlohmann::json::object());
  Call("Log.enable", nlohmann::json::object());
  Call("Page.enable", nlohmann::json::object());
}

HeadlessBrowser::~HeadlessBrowser() {
  socket_.Close();
  if (pid_ > 0) {
    ::kill(-pid_, SIGTERM);
    ::kill(pid_, SIGTERM);
    const auto deadline = Clock::now() + std::chrono::seconds(5);
    int status = 0;
    while (::waitpid(pid_, &status, WNOHANG) != pid_) {
      if (Clock::now() > deadline) {
        ::kill(-pid_, SIGKILL);
        ::kill(pid_, SIGKILL);
        ::waitpid(pid_, &status, 0);
        break;
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
  }
}

nlohmann::json HeadlessBrowser::Call(const std::string& method, const nlohmann::json& params,
                                     bool browser_level) {
  const int id = next_id_++;
  nlohmann::json request = {{"id", id}, {"method", method}, {"params", params}};
  if (!browser_level) request["sessionId"] = session_id_;
  if (!socket_.Send(request.dump())) {
    throw std::runtime_error("the DevTools connection is gone (" + method + ")");
  }
  const auto deadline = Clock::now() + std::chrono::duration<double>(timeout_seconds_);
  while (true) {
    const int left_ms = int(std::chrono::duration<double, std::milli>(deadline - Clock::now())
                                .count());
    if (left_ms <= 0) throw std::runtime_error(method + ": no answer from chromium");
    std::string text;
    const WebSocket::Status status = socket_.Receive(&text, left_ms);
    if (status == WebSocket::Status::kClosed) {
      throw std::runtime_error(method + ": chromium closed the DevTools connection " +
                               socket_.error());
    }
    if (status == WebSocket::Status::kTimeout) continue;
    const nlohmann::json message = nlohmann::json::parse(text);
    if (message.contains("id") && message["id"] == id) {
      if (message.contains("error")) {
        throw std::runtime_error(method + ": " + message["error"].dump());
      }
      return message["result"];
    }
    if (message.contains("method")) OnEvent(message);
  }
}

void HeadlessBrowser::OnEvent(const nlohmann::json& message) {
  const std::string method = message["method"];
  const nlohmann::json& params = message["params"];
  if (method == "Runtime.consoleAPICalled") {
    const std::string type = params.value("type", std::string());
    if (type != "error" && type != "assert") return;
    std::string text = "console." + type + ":";
    for (const nlohmann::json& arg : params["args"]) text += " " + RemoteObjectText(arg);
    errors_.push_back(text);
  } else if (method == "Runtime.exceptionThrown") {
    const nlohmann::json& details = params["exceptionDetails"];
    std::string text = "exception: " + details.value("text", std::string());
    if (details.contains("exception")) text += " " + RemoteObjectText(details["exception"]);
    errors_.push_back(text);
  } else if (method == "Log.entryAdded") {
    const nlohmann::json& entry = params["entry"];
    if (entry.value("level", std::string()) == "error") {
      errors_.push_back("log: " + entry.value("text", std::string()) + " " +
                        entry.value("url", std::string()));
    }
  }
}

void HeadlessBrowser::Navigate(const std::string& url) {
  const nlohmann::json result = Call("Page.navigate", {{"url", url}});
  if (result.contains("errorText")) {
    throw std::runtime_error("cannot open " + url + ": " + result["errorText"].dump());
  }
}

nlohmann::json HeadlessBrowser::Evaluate(const std::string& expression) {
  const nlohmann::json result = Call(
      "Runtime.evaluate",
      {{"expression", expression}, {"returnByValue", true}, {"awaitPromise", true}});
  if (result.contains("exceptionDetails")) {
    throw std::runtime_error("page: " + expression + ": " + result["exceptionDetails"].dump());
  }
  return result["result"].value("value", nlohmann::json());
}

bool HeadlessBrowser::WaitFor(const std::string& expression, double timeout_seconds) {
  const auto deadline = Clock::now() + std::chrono::duration<double>(timeout_seconds);
  while (Clock::now() < deadline) {
    if (Evaluate("Boolean(" + expression + ")") == true) return true;
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  return false;
}

void HeadlessBrowser::Screenshot(const std::filesystem::path& png) {
  const nlohmann::json result = Call("Page.captureScreenshot", {{"format", "png"}});
  std::ofstream out(png, std::ios::binary);
  const std::string bytes = DecodeBase64(result["data"].get<std::string>());
  out.write(bytes.data(), std::streamsize(bytes.size()));
  if (!out) throw std::runtime_error("cannot write " + png.string());
}

}  // namespace flysfm::testing
