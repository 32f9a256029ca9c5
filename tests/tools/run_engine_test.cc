// The engine loop of batch, demo and live (RunEngine) with faults put in
// it: an engine that throws on one image, an engine that kills the process
// during one, an output folder that cannot be written, a second process on
// the same --out.

#include <signal.h>
#include <spawn.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdlib>
#include <fstream>
#include <map>
#include <set>
#include <stdexcept>

#include <catch2/catch.hpp>
#include <nlohmann/json.hpp>

#include "io/run/output_lock.h"
#include "io/synthetic/synthetic_source.h"
#include "tests/io/sources/source_fixture.h"
#include "tests/testing/frame_files.h"
#include "tests/testing/temp_dir.h"
#include "tests/tools/live_process.h"
#include "tools/engine_flags.h"

extern char** environ;

namespace flysfm {
namespace {

namespace fs = std::filesystem;

constexpr int kImages = 4;
// The image the injected faults hit.
const char* const kPoison = "shot01.jpg";
// Where the child process of the crash test runs (set for it only).
const char* const kChildOutVariable = "FLYSFM_TEST_CRASH_OUT";

// The engine's part replaced by a quick stand-in that records what it saw
// (the faults are the point here, not the model).
std::vector<ImageResult> FakeAddImage(std::vector<std::string>* seen, PreparedFrame frame) {
  seen->push_back(frame.frame.name);
  ImageResult result;
  result.name = frame.frame.name;
  result.status = ImageStatus::kPending;
  result.reason = "stand-in";
  return {result};
}

EngineFlags Flags(const fs::path& out) {
  EngineFlags flags;
  flags.out = out.string();
  flags.refresh_seconds = 0;
  return flags;
}

int Run(const fs::path& images, const fs::path& out, RunEngineOptions options) {
  FrameListSource source(ListImageFolder(images));
  Engine engine = EngineFlags().MakeEngine();
  return RunEngine(&source, &engine, Flags(out), options);
}

nlohmann::json Summary(const fs::path& out) {
  return nlohmann::json::parse(testing::ReadText(out / "summary.json"));
}

std::vector<std::string> LoggedNames(const fs::path& out) {
  std::vector<std::string> names;
  for (const std::string& line : testing::LinesStartingWith(out / "log.jsonl", "{")) {
    names.push_back(nlohmann::json::parse(line)["name"].get<std::string>());
  }
  return names;
}

TEST_CASE("An engine exception on one image is counted, quarantined, and the run goes on") {
  const fs::path dir = testing::MakeTempDir("run_engine_throw");
  testing::WriteTestJpegs(dir / "images", kImages);
  const fs::path out = dir / "out";
  std::vector<std::string> seen;
  RunEngineOptions options;
  options.add_image = [&](Engine*, PreparedFrame frame) {
    // A broken invariant: a std::logic_error, not a runtime_error.
    if (frame.frame.name == kPoison) throw std::logic_error("broken invariant");
    return FakeAddImage(&seen, std::move(frame));
  };
  int exit_code = -1;
  REQUIRE_NOTHROW(exit_code = Run(dir / "images", out, options));
  CHECK(exit_code == 0);
  CHECK(seen == std::vector<std::string>{"shot00.jpg", "shot02.jpg", "shot03.jpg"});
  CHECK(Summary(out)["engine_errors"] == 1);
  CHECK(Summary(out)["images_in"] == kImages);
  // The log names every image received, the failed one with its reason.
  const std::vector<std::string> logged = LoggedNames(out);
  CHECK(std::set<std::string>(logged.begin(), logged.end()).size() == std::size_t(kImages));
  CHECK_THAT(testing::ReadText(out / "log.jsonl"), Catch::Contains("broken invariant"));

  // The restart does not give it to the engine again.
  seen.clear();
  options.add_image = [&](Engine*, PreparedFrame frame) {
    return FakeAddImage(&seen, std::move(frame));
  };
  CHECK(Run(dir / "images", out, options) == 0);
  CHECK(seen == std::vector<std::string>{"shot00.jpg", "shot02.jpg", "shot03.jpg"});
  CHECK(Summary(out)["quarantined"] == 1);
}

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
  CHECK(RunEngine(&source, &engine, flags) == 0);
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

TEST_CASE("The flag --lsm-window-budget sets the engine's LSM memory; a negative one is refused") {
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

TEST_CASE("A failed output write is counted and the run goes on") {
  const fs::path dir = testing::MakeTempDir("run_engine_write");
  testing::WriteTestJpegs(dir / "images", kImages);
  const fs::path out = dir / "out";
  fs::create_directories(out);
  // sparse/ cannot be made: every model write fails.
  std::ofstream(out / "sparse") << "not a folder";
  std::vector<std::string> seen;
  RunEngineOptions options;
  options.add_image = [&](Engine*, PreparedFrame frame) {
    return FakeAddImage(&seen, std::move(frame));
  };
  int exit_code = -1;
  REQUIRE_NOTHROW(exit_code = Run(dir / "images", out, options));
  // The final outputs are missing: the exit code says so.
  CHECK(exit_code == 1);
  CHECK(seen.size() == std::size_t(kImages));
  CHECK(LoggedNames(out).size() == std::size_t(kImages));
}

// Run only as the child of the next test (hidden: "[.]"): the engine dies
// (abort) in the middle of kPoison, as a crash inside it would.
TEST_CASE("crash child", "[.]") {
  const char* out = std::getenv(kChildOutVariable);
  REQUIRE(out != nullptr);
  RunEngineOptions options;
  // No core file for an abort on purpose.
  const rlimit no_core = {0, 0};
  ::setrlimit(RLIMIT_CORE, &no_core);
  options.add_image = [](Engine*, PreparedFrame frame) {
    if (frame.frame.name == kPoison) std::abort();
    std::vector<std::string> seen;
    return FakeAddImage(&seen, std::move(frame));
  };
  Run(fs::path(out).parent_path() / "images", out, options);
}

TEST_CASE("After a process crashed on one image, the restart skips that image") {
  const fs::path dir = testing::MakeTempDir("run_engine_crash");
  testing::WriteTestJpegs(dir / "images", kImages);
  const fs::path out = dir / "out";
  const std::string variable = std::string(kChildOutVariable) + "=" + out.string();
  std::vector<char*> environment = {const_cast<char*>(variable.c_str())};
  for (char** entry = environ; *entry != nullptr; ++entry) environment.push_back(*entry);
  environment.push_back(nullptr);
  std::string self = fs::read_symlink("/proc/self/exe").string();
  std::string test_name = "crash child";
  char* argv[] = {self.data(), test_name.data(), nullptr};
  pid_t child = 0;
  REQUIRE(::posix_spawn(&child, self.c_str(), nullptr, nullptr, argv, environment.data()) == 0);
  REQUIRE(testing::WaitForExit(child, 30) == 128 + SIGABRT);

  std::vector<std::string> seen;
  RunEngineOptions options;
  options.add_image = [&](Engine*, PreparedFrame frame) {
    return FakeAddImage(&seen, std::move(frame));
  };
  CHECK(Run(dir / "images", out, options) == 0);
  // The image being decoded ahead when the process died is not blamed.
  CHECK(seen == std::vector<std::string>{"shot00.jpg", "shot02.jpg", "shot03.jpg"});
  CHECK(Summary(out)["quarantined"] == 1);
  CHECK_THAT(testing::ReadText(out / "quarantine.tsv"),
             Catch::Contains(std::string("crashed\t") + kPoison));

  // --retry-quarantined gives it another try.
  seen.clear();
  EngineFlags flags = Flags(out);
  flags.retry_quarantined = true;
  FrameListSource source(ListImageFolder(dir / "images"));
  Engine engine = EngineFlags().MakeEngine();
  CHECK(RunEngine(&source, &engine, flags, options) == 0);
  CHECK(seen.size() == std::size_t(kImages));
}

// A rendered walk as image files, in capture order.
std::vector<Frame> RenderedFolder(const fs::path& dir, Camera* camera) {
  SyntheticCaptureOptions options;
  options.num_views = 10;
  options.seed = 4;
  const SyntheticCapture capture = MakeSyntheticCapture(options);
  *camera = capture.camera;
  testing::WriteFrameFiles(capture.frames, dir);
  return ListImageFolder(dir);
}

TEST_CASE("batch --resume continues the checkpointed model and extends a finished one") {
  const fs::path dir = testing::MakeTempDir("run_engine_resume");
  Camera camera;
  const std::vector<Frame> frames = RenderedFolder(dir / "images", &camera);
  const fs::path out = dir / "out";
  EngineFlags flags = Flags(out);
  flags.camera = camera.ToString();
  const auto run = [&](std::size_t num_frames) {
    FrameListSource source(std::vector<Frame>(frames.begin(), frames.begin() + num_frames));
    Engine engine = flags.MakeEngine();
    REQUIRE(RunEngine(&source, &engine, flags) == 0);
    return Summary(out);
  };

  // The first half, finished; then the whole folder on the same model: only
  // the new images are processed.
  const std::size_t half = frames.size() / 2;
  CHECK(run(half)["resumed_images"] == 0);
  REQUIRE(fs::exists(out / "state" / "snapshot.bin"));
  flags.resume = true;
  nlohmann::json summary = run(frames.size());
  CHECK(summary["resumed_images"] == half);
  CHECK(summary["skipped_in_model"] == half);
  CHECK(summary["images_in"] == frames.size() - half);
  CHECK(summary["registered"] == frames.size());
  const std::vector<std::string> logged = LoggedNames(out);
  CHECK(std::set<std::string>(logged.begin(), logged.end()).size() == frames.size());

  // Nothing new: nothing processed, the model as it was.
  summary = run(frames.size());
  CHECK(summary["images_in"] == 0);
  CHECK(summary["registered"] == frames.size());

  // Without --resume a new model starts.
  flags.resume = false;
  CHECK(run(half)["resumed_images"] == 0);

  // A checkpoint that cannot be read stops the run with the reason and
  // what to do; nothing is overwritten.
  std::ofstream(out / "state" / "snapshot.bin", std::ios::binary | std::ios::trunc) << "junk";
  flags.resume = true;
  FrameListSource source(frames);
  Engine engine = flags.MakeEngine();
  CHECK_THROWS_WITH(RunEngine(&source, &engine, flags),
                    Catch::Contains("cannot resume from") && Catch::Contains("move that folder"));
  CHECK(testing::ReadText(out / "state" / "snapshot.bin") == "junk");
}

TEST_CASE("Paced images are refined between them, and the summary counts it; "
          "--no-refinement refines nothing") {
  const fs::path dir = testing::MakeTempDir("run_engine_refine");
  Camera camera;
  std::vector<Frame> frames = RenderedFolder(dir / "images", &camera);
  frames.resize(6);
  for (const bool refine : {true, false}) {
    const fs::path out = dir / (refine ? "on" : "off");
    EngineFlags flags = Flags(out);
    flags.camera = camera.ToString();
    flags.no_refinement = !refine;
    Engine engine = flags.MakeEngine();
    // Refinement slices done before each image, as the run gave them.
    std::vector<int> slices_before;
    RunEngineOptions options;
    options.add_image = [&](Engine* engine, PreparedFrame frame) {
      slices_before.push_back(engine->refinement_totals().num_slices);
      return engine->AddImage(std::move(frame));
    };
    // One image a second: the engine is idle most of each interval.
    FrameListSource source(frames, 1.0);
    REQUIRE(RunEngine(&source, &engine, flags, options) == 0);
    const nlohmann::json summary = Summary(out);
    CHECK(summary["registered"] == frames.size());
    REQUIRE(slices_before.size() == frames.size());
    if (refine) {
      CHECK(slices_before.back() > 0);
      CHECK(summary["refinement"]["slices"].get<int>() > slices_before.back());
      CHECK(summary["refinement"]["global_bas"].get<int>() >= 1);
    } else {
      CHECK(slices_before.back() == 0);
      CHECK(summary["refinement"]["slices"] == 0);
    }
  }
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
