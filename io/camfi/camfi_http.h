#pragma once

// HTTP calls to a CAMFI transmitter's REST port through libcurl. The request
// target is sent exactly as given: a device path encoded with "/" as %2F must
// reach the device as %2F (../shared/camfi.md 2.2), and libcurl neither
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

  std::string BodyText() const { return std::string(body.begin(), body.end()); }
};

class CamfiHttp {
 public:
  // `password` empty: no credentials. Otherwise user "CamFi" with this
  // password, in whichever scheme (Basic, Digest) the device asks for: the
  // scheme is not known (camfi.md 2.3).
  CamfiHttp(std::string host, int port, std::string password);

  // `timeout_seconds` bounds the whole call; `idle_seconds` > 0 instead
  // aborts a transfer that moves no byte for that long (large downloads).
  // A set `*abort` ends a transfer early (error "aborted").
  HttpResult Get(const std::string& target, double timeout_seconds,
                 double idle_seconds = 0,
                 const std::atomic<bool>* abort = nullptr) const;
  HttpResult Post(const std::string& target, double timeout_seconds) const;

 private:
  HttpResult Perform(const std::string& method, const std::string& target,
                     double timeout_seconds, double idle_seconds,
                     const std::atomic<bool>* abort) const;

  std::string base_url_;
  std::string password_;
};

// The device path as one URL segment: every byte outside [A-Za-z0-9-_.~]
// percent-encoded, "/" included.
std::string EncodeDevicePath(const std::string& device_path);

}  // namespace flysfm
