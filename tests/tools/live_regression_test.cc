// `flysfm live` registers what `flysfm batch` registers on the same files in
// the same order: the engine loop does not know where an image came from.

#include <map>

#include <catch2/catch.hpp>
#include <nlohmann/json.hpp>

#include "io/camfi/camfi_emulator.h"
#include "io/sources/image_source.h"
#include "tests/io/camfi/camfi_fixture.h"
#include "tests/testing/data.h"
#include "tests/testing/temp_dir.h"
#include "tests/tools/live_process.h"

namespace flysfm {
namespace {

// The final status of every image in a run's log (a pending image may be
// logged again once it registers).
std::map<std::string, std::string> FinalStatus(const std::filesystem::path& out) {
  std::map<std::string, std::string> status;
  for (const std::string& line : testing::LinesStartingWith(out / "log.jsonl", "{")) {
    const nlohmann::json result = nlohmann::json::parse(line);
    status[result["name"]] = result["status"];
  }
  return status;
}

TEST_CASE("live from the emulator registers the same images as batch") {
  const std::string sequence =
      testing::DataPath("tum/rgbd_dataset_freiburg3_long_office_household_superglue17");
  std::vector<Frame> frames = ListTumSequence(sequence);
  frames.resize(6);
  CamfiEmulatorOptions options;
  for (const Frame& frame : frames) options.images.push_back(frame.path);
  options.http_port = 0;
  options.event_port = 0;
  options.interval_seconds = 0.5;
  CamfiEmulator emulator(options);
  const std::filesystem::path dir = testing::MakeTempDir("live_vs_batch");
  const std::string camera = "PINHOLE 535.4,539.2,320.1,247.6";

  // Refinement between shots depends on when each shot arrived: without it
  // live and batch build the same model, point for point.
  const pid_t live = testing::SpawnFlysfm(
      {"live", "--camfi", "127.0.0.1:" + std::to_string(emulator.http_port()),
       "--camfi-events-port", std::to_string(emulator.event_port()), "--camera", camera,
       "--max-images", "6", "--no-refinement", "--out", (dir / "live").string()},
      dir / "live.txt");
  REQUIRE(testing::WaitForExit(live, 90) == 0);
  const pid_t batch = testing::SpawnFlysfm(
      {"batch", (dir / "live" / "images").string(), "--camera", camera, "--out",
       (dir / "batch").string()},
      dir / "batch.txt");
  REQUIRE(testing::WaitForExit(batch, 90) == 0);

  const std::map<std::string, std::string> live_status = FinalStatus(dir / "live");
  const std::map<std::string, std::string> batch_status = FinalStatus(dir / "batch");
  CHECK(live_status.size() == 6);
  CHECK(live_status == batch_status);
  int registered = 0;
  for (const auto& [name, status] : live_status) registered += status == "registered";
  CHECK(registered >= 3);
  const nlohmann::json live_summary =
      nlohmann::json::parse(testing::ReadText(dir / "live" / "summary.json"));
  const nlohmann::json batch_summary =
      nlohmann::json::parse(testing::ReadText(dir / "batch" / "summary.json"));
  CHECK(live_summary["registered"] == batch_summary["registered"]);
  CHECK(live_summary["points"] == batch_summary["points"]);
}

}  // namespace
}  // namespace flysfm
