#pragma once

// HTTP calls to a CAMFI transmitter's REST port through libcurl. The request
// target is sent exactly as given: a device path encoded with "/" as %2F must
// reach the device as %2F (docs/camfi.md 2.2), and libcurl neither
// decodes it nor (with PATH_AS_IS) normalises the path.

#include <atomic>
#include <cstdint>
#include <string>
#include <vector>

namespace flysfm {

struct HttpResult {
  // 0 when no HTTP answer arrived (refused, timed out, cut); `error` says why.
  long status = 0;
  std::string error;
  std::vector<std::uint8_t> body;
  // The Content-Length header; -1 when absent.
  long long content_length = -1;
  // Why a transfer was abandoned on our side (`error` says it too).
  bool too_large = false;
  bool timed_out = false;

  std::string BodyText() const { return std::string(body.begin(), body.end()); }
};

// What one call may cost; a call over a bound ends with an error. Every call
// sets `total_seconds` and `max_body_bytes` (> 0): there is no unbounded
// call.
struct HttpLimits {
  // The whole call, from connecting to the last byte.
  double total_seconds = 0;
  // > 0: also ends a transfer that moves no byte for this long (whole
  // seconds: libcurl's resolution).
  double idle_seconds = 0;
  // The body (announced by Content-Length, or counted as it arrives).
  std::uint64_t max_body_bytes = 0;
};

class CamfiHttp {
 public:
  // `password` empty: no credentials. Otherwise user "CamFi" with this
  // password, in whichever scheme (Basic, Digest) the device asks for: the
  // scheme is not known (docs/camfi.md 2.3).
  CamfiHttp(std::string host, int port, std::string password);

  // A set `*abort` ends a transfer early (error "aborted").
  HttpResult Get(const std::string& target, const HttpLimits& limits,
                 const std::atomic<bool>* abort = nullptr) const;
  HttpResult Post(const std::string& target, const HttpLimits& limits) const;

 private:
  HttpResult Perform(const std::string& method, const std::string& target, const HttpLimits& limits,
                     const std::atomic<bool>* abort) const;

  std::string base_url_;
  std::string password_;
};

// The device path as one URL segment: every byte outside [A-Za-z0-9-_.~]
// percent-encoded, "/" included.
std::string EncodeDevicePath(const std::string& device_path);

}  // namespace flysfm
