#pragma once

// Shared by the CAMFI tests: an emulator on loopback (plus the live-source
// helpers of tests/io/sources/source_fixture.h).

#include <filesystem>
#include <vector>

#include "io/camfi/camfi_emulator.h"
#include "io/camfi/camfi_http.h"
#include "tests/io/sources/source_fixture.h"

namespace flysfm::testing {

// An HTTP call to the emulator on loopback: quick, bodies up to 16 MiB.
constexpr HttpLimits kQuickCall{2, 0, std::uint64_t(1) << 24};

// An emulator on loopback, on ports the system picks, shooting `images` every
// `interval_seconds`; `ping_ms` (when > 0) sets its ping interval and timeout
// short, so a dropped or stalled socket is noticed within the test's time.
inline CamfiEmulatorOptions LoopbackEmulator(const std::vector<std::filesystem::path>& images,
                                             double interval_seconds, int ping_interval_ms = 0,
                                             int ping_timeout_ms = 0) {
  CamfiEmulatorOptions options;
  options.images = images;
  options.http_port = 0;
  options.event_port = 0;
  options.interval_seconds = interval_seconds;
  if (ping_interval_ms > 0) options.ping_interval_ms = ping_interval_ms;
  if (ping_timeout_ms > 0) options.ping_timeout_ms = ping_timeout_ms;
  return options;
}

}  // namespace flysfm::testing
