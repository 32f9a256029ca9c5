// The flags the engine-running commands share (batch, demo, live) and the
// run they set up: options reach the engine and the run loop, bad values are
// refused, and a second flysfm on the same --out is refused.

#include "tools/engine_flags.h"

#include <unistd.h>

#include <map>
#include <string>

#include <catch2/catch.hpp>
#include <nlohmann/json.hpp>

#include "io/run/output_lock.h"
#include "tests/io/sources/source_fixture.h"
#include "tests/testing/temp_dir.h"
#include "tests/tools/live_process.h"

namespace flysfm {
namespace {

namespace fs = std::filesystem;

constexpr int kImages = 4;

TEST_CASE("Images over --max-megapixels are rejected before decoding, with the reason logged") {
  const fs::path dir = testing::MakeTempDir("run_engine_megapixels");
  // 64 x 48, 56, 64 and 72 pixels: the last two claim more than 4 000.
  testing::WriteTestJpegs(dir / "images", kImages);
  const fs::path out = dir / "out";
  CLI::App app;
  EngineFlags flags;
  AddEngineFlags(&app, &flags);
  app.parse("--out " + out.string() + " --max-megapixels 0.004 --refresh-seconds 0", false);
  FrameListSource source(ListImageFolder(dir / "images"));
  Engine engine = flags.MakeEngine();
  CHECK(RunFromFlags(&source, &engine, flags) == 0);
  std::map<std::string, std::string> reasons;
  for (const std::string& line : testing::LinesStartingWith(out / "log.jsonl", "{")) {
    const nlohmann::json record = nlohmann::json::parse(line);
    reasons[record["name"].get<std::string>()] = record.value("reason", "");
  }
  REQUIRE(reasons.size() == std::size_t(kImages));
  for (const char* const small : {"shot00.jpg", "shot01.jpg"}) {
    CHECK_THAT(reasons[small], !Catch::Contains("max_image_pixels"));
  }
  for (const char* const large : {"shot02.jpg", "shot03.jpg"}) {
    CHECK_THAT(reasons[large], Catch::Contains("above max_image_pixels"));
  }

  CLI::App bad;
  EngineFlags bad_flags;
  AddEngineFlags(&bad, &bad_flags);
  CHECK_THROWS_AS(bad.parse("--out x --max-megapixels 0", false), CLI::ValidationError);
}

TEST_CASE("The flag --lsm-window-budget sets the engine's LSM memory, a negative one is refused") {
  CLI::App app;
  EngineFlags flags;
  AddEngineFlags(&app, &flags);
  app.parse("--out x --lsm-window-budget 300", false);
  CHECK(flags.MakeEngine().options().lsm_images.window_budget_megabytes == 300);
  CLI::App defaults;
  EngineFlags default_flags;
  AddEngineFlags(&defaults, &default_flags);
  defaults.parse("--out x", false);
  CHECK(default_flags.MakeEngine().options().lsm_images.window_budget_megabytes ==
        LsmImageStore::Options().window_budget_megabytes);
  CLI::App bad;
  EngineFlags bad_flags;
  AddEngineFlags(&bad, &bad_flags);
  CHECK_THROWS_AS(bad.parse("--out x --lsm-window-budget -1", false), CLI::ValidationError);
}

TEST_CASE("A second flysfm on the same --out fails at once, naming the first") {
  const fs::path dir = testing::MakeTempDir("run_engine_lock");
  testing::WriteTestJpegs(dir / "images", kImages);
  const fs::path out = dir / "out";
  const OutputLock held(out);
  const pid_t pid = testing::SpawnFlysfm({"batch", (dir / "images").string(), "--out",
                                          out.string()},
                                         dir / "second.txt");
  CHECK(testing::WaitForExit(pid, 20) == 1);
  CHECK_THAT(testing::ReadText(dir / "second.txt"),
             Catch::Contains("in use by another flysfm process (pid " +
                             std::to_string(::getpid()) + ")"));
  CHECK_FALSE(fs::exists(out / "log.jsonl"));
  // In the same process too: the lock is per open file.
  CHECK_THROWS_WITH(OutputLock(out), Catch::Contains("in use"));
}

}  // namespace
}  // namespace flysfm
