// `flysfm live --camfi` killed with SIGKILL at random moments of a session
// and restarted each time: the model resumes from its checkpoint, and at the
// end every shot is stored once, fetched once and registered once. A
// regression test (the Release build only): it runs for a minute or two.

#include <algorithm>
#include <fstream>
#include <map>
#include <random>
#include <regex>
#include <set>
#include <thread>

#include <catch2/catch.hpp>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>

#include "io/camfi/camfi_client.h"
#include "io/camfi/camfi_emulator.h"
#include "io/camfi/camfi_http.h"
#include "io/sources/image_markers.h"
#include "io/sources/journal_file.h"
#include "io/synthetic/synthetic_source.h"
#include "tests/io/camfi/camfi_fixture.h"
#include "tests/testing/temp_dir.h"
#include "tests/tools/live_process.h"
#include "tests/testing/rendered_capture.h"

namespace flysfm {
namespace {

namespace fs = std::filesystem;

constexpr int kShots = 40;
constexpr int kKills = 10;

// A rendered walk of kShots views, as the camera's JPEG files.
struct Session {
  Camera camera;
  std::vector<fs::path> images;
};

Session RenderSession(const fs::path& dir) {
  SyntheticCaptureOptions options;
  options.num_views = kShots;
  options.seed = 11;
  const SyntheticCapture capture = testing::RenderedCapture(options);
  Session session{capture.camera, {}};
  fs::create_directories(dir);
  for (const Frame& frame : capture.frames) {
    const cv::Mat image = cv::imdecode(frame.bytes, cv::IMREAD_COLOR);
    std::vector<std::uint8_t> jpeg;
    cv::imencode(".jpg", image, jpeg, {cv::IMWRITE_JPEG_QUALITY, 95});
    const fs::path path = dir / (fs::path(frame.name).stem().string() + ".jpg");
    std::ofstream(path, std::ios::binary)
        .write(reinterpret_cast<const char*>(jpeg.data()), std::streamsize(jpeg.size()));
    session.images.push_back(path);
  }
  return session;
}

// The image names of the COLMAP text model's images.txt.
std::vector<std::string> ModelImageNames(const fs::path& images_txt) {
  std::vector<std::string> names;
  std::ifstream in(images_txt);
  bool pose_line = true;
  for (std::string line; std::getline(in, line);) {
    if (line.empty() || line[0] == '#') continue;
    if (pose_line) names.push_back(line.substr(line.rfind(' ') + 1));
    pose_line = !pose_line;
  }
  return names;
}

TEST_CASE("live: killed at 10 random moments, every shot is stored, fetched and registered once") {
  const fs::path dir = testing::MakeTempDir("live_resume");
  const Session session = RenderSession(dir / "shots");
  CamfiEmulator emulator(testing::LoopbackEmulator(session.images, 0.4));
  const fs::path out = dir / "out";
  const fs::path journal = out / "images" / "journal.tsv";
  const std::vector<std::string> args = {
      "live",          "--camfi",
      "127.0.0.1:" + std::to_string(emulator.http_port()),
      "--camfi-events-port", std::to_string(emulator.event_port()),
      "--camfi-reconcile-seconds", "0.5",
      "--camera",      session.camera.ToString(),
      "--out",         out.string()};
  const auto num_logged = [&] { return testing::LinesStartingWith(out / "log.jsonl", "{").size(); };

  std::mt19937 random(20261202);
  std::uniform_real_distribution<double> delay_seconds(0.0, 1.5);
  // Per kill: the shots stored before it and how many requests the device
  // had seen, so that a later fetch of a stored shot is found.
  std::vector<std::pair<std::vector<std::string>, std::size_t>> kills;
  for (int k = 0; k < kKills; ++k) {
    const std::size_t logged = num_logged();
    const pid_t pid = testing::SpawnFlysfm(args, dir / ("run" + std::to_string(k) + ".txt"));
    // Each run gets at least one result through before it is killed at a
    // random moment after that (a download, a journal append, the engine, a
    // checkpoint write). Two kills in a row may land on the same photo: a
    // death without a crash report never sets a photo aside.
    REQUIRE(testing::WaitUntil([&] { return num_logged() > logged; }, 60));
    std::this_thread::sleep_for(std::chrono::duration<double>(delay_seconds(random)));
    ::kill(pid, SIGKILL);
    REQUIRE(testing::WaitForExit(pid, 5) == 128 + SIGKILL);
    kills.emplace_back(testing::LinesStartingWith(journal, "stored\t"),
                       emulator.RequestLog().size());
  }
  std::vector<std::string> last_args = args;
  last_args.insert(last_args.end(), {"--max-images", std::to_string(kShots)});
  REQUIRE(testing::WaitForExit(testing::SpawnFlysfm(last_args, dir / "last.txt"), 300) == 0);

  // Every shot stored once, byte-identical.
  const std::vector<std::string> stored = testing::LinesStartingWith(journal, "stored\t");
  CHECK(stored.size() == std::size_t(kShots));
  std::set<std::string> names;
  for (int i = 0; i < kShots; ++i) {
    const std::string name = StoreNameForDevicePath(emulator.DevicePath(i));
    names.insert(name);
    CHECK(ReadFileBytes(out / "images" / name) == ReadFileBytes(session.images[std::size_t(i)]));
  }
  // No restart fetched a shot stored before it.
  const std::vector<std::string> requests = emulator.RequestLog();
  for (const auto& [stored_before, num_requests] : kills) {
    for (const std::string& line : stored_before) {
      const std::string device_path = line.substr(7, line.find('\t', 7) - 7);
      const std::string request = "GET /raw/" + EncodeDevicePath(device_path);
      CHECK(std::find(requests.begin() + std::ptrdiff_t(num_requests), requests.end(),
                      request) == requests.end());
    }
  }
  // Registered once each: the model holds every shot, by its stored name,
  // once.
  std::vector<std::string> in_model = ModelImageNames(out / "sparse" / "images.txt");
  std::sort(in_model.begin(), in_model.end());
  CHECK(std::adjacent_find(in_model.begin(), in_model.end()) == in_model.end());
  CHECK(std::set<std::string>(in_model.begin(), in_model.end()) == names);
  const nlohmann::json summary = nlohmann::json::parse(testing::ReadText(out / "summary.json"));
  CHECK(summary["registered"].get<int>() == kShots);
  CHECK(summary["quarantined"].get<int>() == 0);
  // The restarts resumed the model rather than replaying the shots. A kill
  // in the few milliseconds between a run's first result and its first
  // checkpoint leaves the next run nothing to resume: one such run allowed.
  int resumed_runs = 0;
  for (int k = 1; k <= kKills; ++k) {
    const fs::path output = k < kKills ? dir / ("run" + std::to_string(k) + ".txt")
                                       : dir / "last.txt";
    resumed_runs += testing::ReadText(output).find("resumed: ") != std::string::npos;
  }
  CHECK(resumed_runs >= kKills - 1);
  CHECK(summary["resumed_images"].get<int>() > 0);
}

}  // namespace
}  // namespace flysfm
