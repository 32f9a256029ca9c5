#include "io/camfi/camfi_http.h"

#include <algorithm>
#include <mutex>

#include <curl/curl.h>

namespace flysfm {
namespace {

struct Sink {
  std::vector<std::uint8_t>* body;
  std::uint64_t max_bytes;
  bool over = false;
};

// A body without Content-Length (chunked, or a lying server) is bounded as
// it arrives: returning less than given makes libcurl end the transfer.
std::size_t AppendBody(char* data, std::size_t size, std::size_t count, void* user) {
  auto* sink = static_cast<Sink*>(user);
  if (sink->body->size() + size * count > sink->max_bytes) {
    sink->over = true;
    return 0;
  }
  sink->body->insert(sink->body->end(), data, data + size * count);
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

HttpResult CamfiHttp::Get(const std::string& target, const HttpLimits& limits,
                          const std::atomic<bool>* abort) const {
  return Perform("GET", target, limits, abort);
}

HttpResult CamfiHttp::Post(const std::string& target, const HttpLimits& limits) const {
  return Perform("POST", target, limits, nullptr);
}

HttpResult CamfiHttp::Perform(const std::string& method, const std::string& target,
                              const HttpLimits& limits, const std::atomic<bool>* abort) const {
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
  Sink sink{&result.body, limits.max_body_bytes};
  curl_easy_setopt(curl, CURLOPT_WRITEFUNCTION, AppendBody);
  curl_easy_setopt(curl, CURLOPT_WRITEDATA, &sink);
  // Refuses at once a body whose Content-Length is over the bound.
  curl_easy_setopt(curl, CURLOPT_MAXFILESIZE_LARGE, curl_off_t(limits.max_body_bytes));
  curl_easy_setopt(curl, CURLOPT_NOPROGRESS, 0L);
  curl_easy_setopt(curl, CURLOPT_XFERINFOFUNCTION, CheckAbort);
  curl_easy_setopt(curl, CURLOPT_XFERINFODATA, abort);
  curl_easy_setopt(curl, CURLOPT_CONNECTTIMEOUT_MS,
                   long(1000 * std::min(limits.total_seconds, 5.0)));
  curl_easy_setopt(curl, CURLOPT_TIMEOUT_MS, long(1000 * limits.total_seconds));
  if (limits.idle_seconds > 0) {
    curl_easy_setopt(curl, CURLOPT_LOW_SPEED_LIMIT, 1L);
    curl_easy_setopt(curl, CURLOPT_LOW_SPEED_TIME, long(std::max(1.0, limits.idle_seconds)));
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
    result.too_large = sink.over || code == CURLE_FILESIZE_EXCEEDED;
    result.timed_out = code == CURLE_OPERATION_TIMEDOUT;
    if (result.too_large) {
      result.error = "body over " + std::to_string(limits.max_body_bytes) + " bytes";
    } else if (code == CURLE_ABORTED_BY_CALLBACK) {
      result.error = "aborted";
    } else {
      result.error = curl_easy_strerror(code);
    }
    // An answer cut short is no answer.
    result.status = 0;
  }
  curl_easy_cleanup(curl);
  return result;
}

}  // namespace flysfm
