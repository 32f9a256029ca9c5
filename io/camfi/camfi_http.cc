#include "io/camfi/camfi_http.h"

#include <algorithm>
#include <mutex>

#include <curl/curl.h>

namespace flysfm {
namespace {

std::size_t AppendBody(char* data, std::size_t size, std::size_t count, void* user) {
  auto* body = static_cast<std::vector<std::uint8_t>*>(user);
  body->insert(body->end(), data, data + size * count);
  return size * count;
}

int CheckAbort(void* user, curl_off_t, curl_off_t, curl_off_t, curl_off_t) {
  const auto* abort = static_cast<const std::atomic<bool>*>(user);
  return abort != nullptr && abort->load() ? 1 : 0;
}

}  // namespace

std::string EncodeDevicePath(const std::string& device_path) {
  static const char kHex[] = "0123456789ABCDEF";
  std::string encoded;
  for (const char c : device_path) {
    const auto byte = static_cast<unsigned char>(c);
    if ((byte >= 'A' && byte <= 'Z') || (byte >= 'a' && byte <= 'z') ||
        (byte >= '0' && byte <= '9') || byte == '-' || byte == '_' || byte == '.' ||
        byte == '~') {
      encoded.push_back(c);
    } else {
      encoded.push_back('%');
      encoded.push_back(kHex[byte >> 4]);
      encoded.push_back(kHex[byte & 0xF]);
    }
  }
  return encoded;
}

CamfiHttp::CamfiHttp(std::string host, int port, std::string password)
    : base_url_("http://" + host + ":" + std::to_string(port)),
      password_(std::move(password)) {
  static std::once_flag once;
  std::call_once(once, [] { curl_global_init(CURL_GLOBAL_DEFAULT); });
}

HttpResult CamfiHttp::Get(const std::string& target, double timeout_seconds,
                          double idle_seconds, const std::atomic<bool>* abort) const {
  return Perform("GET", target, timeout_seconds, idle_seconds, abort);
}

HttpResult CamfiHttp::Post(const std::string& target, double timeout_seconds) const {
  return Perform("POST", target, timeout_seconds, 0, nullptr);
}

HttpResult CamfiHttp::Perform(const std::string& method, const std::string& target,
                              double timeout_seconds, double idle_seconds,
                              const std::atomic<bool>* abort) const {
  HttpResult result;
  CURL* curl = curl_easy_init();
  if (curl == nullptr) {
    result.error = "cannot create an HTTP handle";
    return result;
  }
  const std::string url = base_url_ + target;
  curl_easy_setopt(curl, CURLOPT_URL, url.c_str());
  curl_easy_setopt(curl, CURLOPT_PATH_AS_IS, 1L);
  curl_easy_setopt(curl, CURLOPT_NOSIGNAL, 1L);
  curl_easy_setopt(curl, CURLOPT_WRITEFUNCTION, AppendBody);
  curl_easy_setopt(curl, CURLOPT_WRITEDATA, &result.body);
  curl_easy_setopt(curl, CURLOPT_NOPROGRESS, 0L);
  curl_easy_setopt(curl, CURLOPT_XFERINFOFUNCTION, CheckAbort);
  curl_easy_setopt(curl, CURLOPT_XFERINFODATA, abort);
  const long connect_ms = long(1000 * std::min(timeout_seconds > 0 ? timeout_seconds : 5.0, 5.0));
  curl_easy_setopt(curl, CURLOPT_CONNECTTIMEOUT_MS, connect_ms);
  if (idle_seconds > 0) {
    curl_easy_setopt(curl, CURLOPT_LOW_SPEED_LIMIT, 1L);
    curl_easy_setopt(curl, CURLOPT_LOW_SPEED_TIME, long(std::max(1.0, idle_seconds)));
  } else {
    curl_easy_setopt(curl, CURLOPT_TIMEOUT_MS, long(1000 * timeout_seconds));
  }
  if (method == "POST") {
    curl_easy_setopt(curl, CURLOPT_POST, 1L);
    curl_easy_setopt(curl, CURLOPT_POSTFIELDS, "");
    curl_easy_setopt(curl, CURLOPT_POSTFIELDSIZE, 0L);
  }
  if (!password_.empty()) {
    curl_easy_setopt(curl, CURLOPT_HTTPAUTH, CURLAUTH_ANY);
    curl_easy_setopt(curl, CURLOPT_USERNAME, "CamFi");
    curl_easy_setopt(curl, CURLOPT_PASSWORD, password_.c_str());
  }
  const CURLcode code = curl_easy_perform(curl);
  curl_easy_getinfo(curl, CURLINFO_RESPONSE_CODE, &result.status);
  curl_off_t length = -1;
  curl_easy_getinfo(curl, CURLINFO_CONTENT_LENGTH_DOWNLOAD_T, &length);
  result.content_length = length;
  if (code != CURLE_OK) {
    result.error = code == CURLE_ABORTED_BY_CALLBACK ? "aborted" : curl_easy_strerror(code);
    // An answer cut short is no answer.
    result.status = 0;
  }
  curl_easy_cleanup(curl);
  return result;
}

}  // namespace flysfm
