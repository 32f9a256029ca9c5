#include "io/camfi/camfi_http.h"

#include <catch2/catch.hpp>

#include "io/camfi/camfi_emulator.h"
#include "tests/io/camfi/camfi_fixture.h"
#include "tests/testing/temp_dir.h"

namespace flysfm {
namespace {

TEST_CASE("EncodeDevicePath keeps the path one segment") {
  CHECK(EncodeDevicePath("/store_00010001/DCIM/100CANON/IMG_0001.JPG") ==
        "%2Fstore_00010001%2FDCIM%2F100CANON%2FIMG_0001.JPG");
  CHECK(EncodeDevicePath("/a b/c+d~e") == "%2Fa%20b%2Fc%2Bd~e");
}

// An emulator on free ports whose camera has taken one test JPEG.
struct OneShotEmulator {
  static CamfiEmulatorOptions Options(const std::string& name) {
    CamfiEmulatorOptions options;
    options.images = testing::WriteTestJpegs(testing::MakeTempDir(name), 1);
    options.http_port = 0;
    options.event_port = 0;
    return options;
  }
  explicit OneShotEmulator(const std::string& name) : options(Options(name)), emulator(options) {
    emulator.Shoot();
  }
  const CamfiEmulatorOptions options;
  CamfiEmulator emulator;
};

TEST_CASE("CamfiHttp sends %2F as is and reports failures") {
  OneShotEmulator shot("camfi_http");
  CamfiEmulator& emulator = shot.emulator;
  const CamfiHttp http("127.0.0.1", emulator.http_port(), "");
  const HttpResult raw =
      http.Get("/raw/" + EncodeDevicePath(emulator.DevicePath(0)), testing::kQuickCall);
  CHECK(raw.status == 200);
  CHECK(raw.error.empty());
  CHECK(raw.content_length == (long long)raw.body.size());
  CHECK(emulator.RequestLog().back() ==
        "GET /raw/%2Fstore_00010001%2FDCIM%2F100CANON%2FIMG_0001.JPG");
  CHECK(http.Get("/raw/%2Fno%2Fsuch.JPG", testing::kQuickCall).status == 500);
  CHECK(http.Post("/tether/start", testing::kQuickCall).status == 200);
}

TEST_CASE("CamfiHttp abandons a body over its bound") {
  OneShotEmulator shot("camfi_http_bound");
  CamfiEmulator& emulator = shot.emulator;
  const CamfiEmulatorOptions& options = shot.options;
  const std::string target = "/raw/" + EncodeDevicePath(emulator.DevicePath(0));
  const std::uint64_t size = std::filesystem::file_size(options.images[0]);
  const CamfiHttp http("127.0.0.1", emulator.http_port(), "");
  const HttpResult over = http.Get(target, {2, 0, size - 1});
  CHECK(over.too_large);
  CHECK(over.status == 0);
  CHECK(over.body.size() < size);
  CHECK_THAT(over.error, Catch::Contains("body over"));
  const HttpResult exact = http.Get(target, {2, 0, size});
  CHECK_FALSE(exact.too_large);
  CHECK(exact.body.size() == size);
}

TEST_CASE("CamfiHttp reports a refused connection as an error and no status") {
  int port = 0;
  {
    CamfiEmulatorOptions options;
    options.http_port = 0;
    options.event_port = 0;
    const std::filesystem::path dir = testing::MakeTempDir("camfi_http_refused");
    options.images = testing::WriteTestJpegs(dir, 1);
    CamfiEmulator emulator(options);
    port = emulator.http_port();
  }
  const HttpResult result = CamfiHttp("127.0.0.1", port, "").Get("/info", testing::kQuickCall);
  CHECK(result.status == 0);
  CHECK_FALSE(result.error.empty());
}

}  // namespace
}  // namespace flysfm
