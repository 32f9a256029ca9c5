// The run loop with faults put in it: an engine that throws on one image, an
// engine that kills the process during one, an output folder that cannot be
// written; resuming a checkpointed model; refinement between paced images.

#include <signal.h>
#include <spawn.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cstdlib>
#include <fstream>
#include <map>
#include <regex>
#include <set>
#include <stdexcept>
#include <thread>

#include <catch2/catch.hpp>
#include <nlohmann/json.hpp>

#include "io/run/run_loop.h"
#include "io/sources/journal_file.h"
#include "io/sources/merged_source.h"
#include "io/synthetic/synthetic_source.h"
#include "tests/io/sources/source_fixture.h"
#include "tests/testing/frame_files.h"
#include "tests/testing/temp_dir.h"
#include "tests/testing/process.h"
#include "tests/testing/rendered_capture.h"
#include "tests/testing/sanitizer.h"

extern char** environ;

namespace flysfm {
namespace {

namespace fs = std::filesystem;

constexpr int kImages = 4;
// The image the injected faults hit.
const char* const kPoison = "shot01.jpg";
// Where the child process of the crash and kill tests runs (set for it
// only).
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

RunLoop::Options OptionsFor(const fs::path& out) {
  RunLoop::Options options;
  options.out = out.string();
  options.refresh_seconds = 0;
  return options;
}

int Run(const fs::path& images, const RunLoop::Hooks& hooks, RunLoop::Options options) {
  FrameListSource source(ListImageFolder(images));
  Engine engine{Engine::Options()};
  return RunLoop(std::move(options)).Run(&source, &engine, hooks).exit_code;
}

int Run(const fs::path& images, const fs::path& out, const RunLoop::Hooks& hooks) {
  return Run(images, hooks, OptionsFor(out));
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
  RunLoop::Hooks options;
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

TEST_CASE("A failed output write is counted and the run goes on") {
  const fs::path dir = testing::MakeTempDir("run_engine_write");
  testing::WriteTestJpegs(dir / "images", kImages);
  const fs::path out = dir / "out";
  fs::create_directories(out);
  // sparse/ cannot be made: every model write fails.
  std::ofstream(out / "sparse") << "not a folder";
  std::vector<std::string> seen;
  RunLoop::Hooks options;
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

// This test program again, running only the hidden test case `test_name`
// with `out` as its output folder.
pid_t SpawnChild(std::string test_name, const fs::path& out) {
  const std::string variable = std::string(kChildOutVariable) + "=" + out.string();
  std::vector<char*> environment = {const_cast<char*>(variable.c_str())};
  for (char** entry = environ; *entry != nullptr; ++entry) environment.push_back(*entry);
  environment.push_back(nullptr);
  std::string self = fs::read_symlink("/proc/self/exe").string();
  char* argv[] = {self.data(), test_name.data(), nullptr};
  pid_t child = 0;
  REQUIRE(::posix_spawn(&child, self.c_str(), nullptr, nullptr, argv, environment.data()) == 0);
  return child;
}

// Run only as the child of the next test (hidden: "[.]"): the engine dies
// (abort) in the middle of kPoison, as a crash inside it would.
TEST_CASE("crash child", "[.]") {
  const char* out = std::getenv(kChildOutVariable);
  REQUIRE(out != nullptr);
  RunLoop::Hooks options;
  // No core file for an abort on purpose, and the default actions under the
  // quarantine's handler, as in the program: Catch2's handler would take
  // over after it, and report (allocating) inside the signal.
  const rlimit no_core = {0, 0};
  ::setrlimit(RLIMIT_CORE, &no_core);
  for (const int signal : {SIGSEGV, SIGBUS, SIGILL, SIGFPE, SIGABRT}) ::signal(signal, SIG_DFL);
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
  REQUIRE(testing::WaitForExit(SpawnChild("crash child", out), 30) == 128 + SIGABRT);

  std::vector<std::string> seen;
  RunLoop::Hooks options;
  options.add_image = [&](Engine*, PreparedFrame frame) {
    return FakeAddImage(&seen, std::move(frame));
  };
  CHECK(Run(dir / "images", out, options) == 0);
  // The image being decoded ahead when the process died is not blamed.
  CHECK(seen == std::vector<std::string>{"shot00.jpg", "shot02.jpg", "shot03.jpg"});
  CHECK(Summary(out)["quarantined"] == 1);
  CHECK_THAT(testing::ReadText(out / "quarantine.tsv"),
             Catch::Contains(std::string("crashed\t") + kPoison));

  // retry_quarantined (--retry-quarantined) gives it another try.
  seen.clear();
  RunLoop::Options retry = OptionsFor(out);
  retry.retry_quarantined = true;
  CHECK(Run(dir / "images", options, retry) == 0);
  CHECK(seen.size() == std::size_t(kImages));
}

// Run only as the child of the next test: the engine stays on kPoison (a
// bounded sleep: an orphan ends by itself) until it is killed from outside.
TEST_CASE("kill child", "[.]") {
  const char* out = std::getenv(kChildOutVariable);
  REQUIRE(out != nullptr);
  RunLoop::Hooks options;
  options.add_image = [](Engine*, PreparedFrame frame) {
    if (frame.frame.name == kPoison) std::this_thread::sleep_for(std::chrono::seconds(30));
    std::vector<std::string> seen;
    return FakeAddImage(&seen, std::move(frame));
  };
  Run(fs::path(out).parent_path() / "images", out, options);
}

TEST_CASE("Killed from outside on the same image again and again, the restart processes it") {
  const fs::path dir = testing::MakeTempDir("run_engine_kill");
  testing::WriteTestJpegs(dir / "images", kImages);
  const fs::path out = dir / "out";
  const fs::path journal = out / "quarantine.tsv";
  const std::string in_engine = std::string("engine\t") + kPoison;
  constexpr int kKills = 3;
  for (int death = 0; death < kKills; ++death) {
    const pid_t child = SpawnChild("kill child", out);
    // Each run gets to kPoison again (a quarantined image would never reach
    // the engine), and is SIGKILLed there, as a user, the OOM killer or a
    // power cut would end it.
    const bool in_it = testing::WaitUntil(
        [&] { return testing::LinesStartingWith(journal, in_engine).size() > std::size_t(death); },
        10);
    ::kill(child, SIGKILL);
    const int exit_code = testing::WaitForExit(child, 5);
    REQUIRE(in_it);
    REQUIRE(exit_code == 128 + SIGKILL);
  }
  CHECK(testing::LinesStartingWith(journal, in_engine).size() == std::size_t(kKills));

  std::vector<std::string> seen;
  RunLoop::Hooks options;
  options.add_image = [&](Engine*, PreparedFrame frame) {
    return FakeAddImage(&seen, std::move(frame));
  };
  CHECK(Run(dir / "images", out, options) == 0);
  CHECK(seen == std::vector<std::string>{"shot00.jpg", "shot01.jpg", "shot02.jpg", "shot03.jpg"});
  CHECK(Summary(out)["quarantined"] == 0);
  const std::vector<std::string> logged = LoggedNames(out);
  CHECK(std::count(logged.begin(), logged.end(), kPoison) == 1);
  // Every death is on record, none as a quarantine.
  std::map<std::string, int> kinds;
  for (const std::vector<std::string>& record : JournalFile::Read(journal)) {
    if (record.size() >= 2 && record[1] == kPoison) ++kinds[record[0]];
  }
  CHECK(kinds["killed"] == kKills);
  CHECK(kinds["done"] == 1);
  CHECK(kinds.count("crashed") == 0);
  CHECK(kinds.count("failed") == 0);
  CHECK(kinds.count("poison") == 0);
}

// A rendered walk as image files, in capture order.
std::vector<Frame> RenderedFolder(const fs::path& dir, Camera* camera) {
  SyntheticCaptureOptions options;
  options.num_views = testing::kSanitizerBuild ? 8 : 10;  // tests/testing/sanitizer.h
  options.seed = 4;
  const SyntheticCapture capture = testing::RenderedCapture(options);
  *camera = capture.camera;
  testing::WriteFrameFiles(capture.frames, dir);
  return ListImageFolder(dir);
}

TEST_CASE("Resuming continues the checkpointed model and extends a finished one") {
  const fs::path dir = testing::MakeTempDir("run_engine_resume");
  Camera camera;
  const std::vector<Frame> frames = RenderedFolder(dir / "images", &camera);
  const fs::path out = dir / "out";
  RunLoop::Options options = OptionsFor(out);
  const auto run = [&](std::size_t num_frames) {
    FrameListSource source(std::vector<Frame>(frames.begin(), frames.begin() + num_frames));
    Engine engine(Engine::Options(), camera);
    REQUIRE(RunLoop(options).Run(&source, &engine).exit_code == 0);
    return Summary(out);
  };

  // The first half, finished; then the whole folder on the same model: only
  // the new images are processed.
  const std::size_t half = frames.size() / 2;
  CHECK(run(half)["resumed_images"] == 0);
  REQUIRE(fs::exists(out / "state" / "snapshot.bin"));
  options.resume = true;
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
  options.resume = false;
  CHECK(run(half)["resumed_images"] == 0);

  // A checkpoint that cannot be read stops the run with the reason and
  // what to do; nothing is overwritten.
  std::ofstream(out / "state" / "snapshot.bin", std::ios::binary | std::ios::trunc) << "junk";
  options.resume = true;
  FrameListSource source(frames);
  Engine engine(Engine::Options(), camera);
  CHECK_THROWS_WITH(RunLoop(options).Run(&source, &engine),
                    Catch::Contains("cannot resume from") && Catch::Contains("move that folder"));
  CHECK(testing::ReadText(out / "state" / "snapshot.bin") == "junk");
}

TEST_CASE("Merged sources' <tag>/ names go through the log, summary, quarantine and resume") {
  const fs::path dir = testing::MakeTempDir("run_engine_sources");
  Camera camera;
  const std::vector<Frame> frames = RenderedFolder(dir / "images", &camera);
  // Two photographers: every other view each.
  std::vector<Frame> alice, bob;
  for (std::size_t i = 0; i < frames.size(); ++i) (i % 2 == 0 ? alice : bob).push_back(frames[i]);
  const std::string poison = "bob/" + bob.back().name;
  const fs::path out = dir / "out";
  RunLoop::Options options = OptionsFor(out);
  options.sources = {"alice", "bob"};
  RunLoop::Hooks hooks;
  hooks.add_image = [&](Engine* engine, PreparedFrame frame) {
    if (frame.frame.name == poison) throw std::runtime_error("bad shot");
    return engine->AddImage(std::move(frame));
  };
  const auto run = [&] {
    FrameListSource a(alice), b(bob);
    MergedSource merged({{"alice", &a}, {"bob", &b}}, {MergedSourceOptions::Order::kRoundRobin});
    Engine engine(Engine::Options(), camera);
    REQUIRE(RunLoop(options).Run(&merged, &engine, hooks).exit_code == 0);
    return Summary(out);
  };
  nlohmann::json summary = run();
  // Every record names its source, and its name starts with the tag.
  std::set<std::string> names;
  for (const std::string& line : testing::LinesStartingWith(out / "log.jsonl", "{")) {
    const nlohmann::json record = nlohmann::json::parse(line);
    const std::string name = record["name"];
    names.insert(name);
    CHECK(name.rfind(record["source"].get<std::string>() + "/", 0) == 0);
  }
  CHECK(names.size() == frames.size());
  CHECK(names.count(poison) == 1);
  CHECK(summary["engine_errors"] == 1);
  // Per source, counts adding up to the run's: every view but the poisoned
  // one registers (the walk registers whole, "Resuming ..." above).
  const auto check_sources = [&](const nlohmann::json& summary, int images_in) {
    const nlohmann::json& sources = summary["sources"];
    REQUIRE(sources.size() == 2);
    CHECK(sources[0]["tag"] == "alice");
    CHECK(sources[1]["tag"] == "bob");
    CHECK(sources[0]["registered"] == alice.size());
    CHECK(sources[1]["registered"] == bob.size() - 1);
    int sum_in = 0, sum_registered = 0, sum_rejected = 0, sum_pending = 0;
    for (const nlohmann::json& source : sources) {
      sum_in += source["images_in"].get<int>();
      sum_registered += source["registered"].get<int>();
      sum_rejected += source["rejected"].get<int>();
      sum_pending += source["pending"].get<int>();
    }
    CHECK(sum_in == images_in);
    CHECK(sum_in == summary["images_in"]);
    CHECK(sum_registered == summary["registered"]);
    CHECK(sum_rejected == summary["rejected"]);
    CHECK(std::size_t(sum_pending) == summary["pending"].size());
  };
  check_sources(summary, int(frames.size()));
  CHECK(summary["sources"][1]["rejected"] == 1);
  const std::vector<std::string> records =
      testing::LinesStartingWith(out / "quarantine.tsv", "failed\t");
  REQUIRE(records.size() == 1);
  CHECK(records[0].rfind("failed\t" + poison + "\t", 0) == 0);

  // The restart resumes the model by those names: nothing is processed
  // again, the poisoned one stays out, and the counts come from the names.
  options.resume = true;
  summary = run();
  CHECK(summary["resumed_images"] == frames.size() - 1);
  CHECK(summary["skipped_in_model"] == frames.size() - 1);
  CHECK(summary["quarantined"] == 1);
  check_sources(summary, 0);
}

TEST_CASE("Paced images are refined between them, and the summary counts it, "
          "an engine without refinement refines nothing") {
  const fs::path dir = testing::MakeTempDir("run_engine_refine");
  Camera camera;
  std::vector<Frame> frames = RenderedFolder(dir / "images", &camera);
  // Two wait for a pair, the third initialises: refinement has an image's
  // interval after it to run in.
  frames.resize(testing::kSanitizerBuild ? 4 : 6);
  for (const bool refine : {true, false}) {
    const fs::path out = dir / (refine ? "on" : "off");
    Engine::Options engine_options;
    engine_options.refinement.enabled = refine;
    Engine engine(engine_options, camera);
    // Refinement slices done before each image, as the run gave them.
    std::vector<int> slices_before;
    RunLoop::Hooks options;
    options.add_image = [&](Engine* engine, PreparedFrame frame) {
      slices_before.push_back(engine->refinement_totals().num_slices);
      return engine->AddImage(std::move(frame));
    };
    // The engine idle most of each interval: an image takes 0.3 s in
    // Release, up to 3 s under ThreadSanitizer.
    FrameListSource source(frames, testing::kSanitizerBuild ? 5.0 : 1.0);
    REQUIRE(RunLoop(OptionsFor(out)).Run(&source, &engine, options).exit_code == 0);
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

TEST_CASE("A long end says what it does, in lines a script can read") {
  SyntheticCaptureOptions capture_options;
  capture_options.num_views = 6;
  capture_options.seed = 4;
  const SyntheticCapture capture = testing::RenderedCapture(capture_options);
  Engine engine(Engine::Options(), capture.camera);
  // The engine's own end, then 1.5 s more of a global BA's iterations, told
  // as Finish tells them: an end as long as a large model's.
  RunLoop::Hooks hooks;
  hooks.finish = [](Engine* engine,
                    const std::function<void(const Engine::FinishProgress&)>& progress) {
    std::vector<ImageResult> results = engine->Finish(progress);
    Engine::FinishProgress state;
    state.step = Engine::FinishProgress::Step::kAdjust;
    state.max_iterations = 15;
    for (; state.iteration < state.max_iterations; ++state.iteration) {
      state.elapsed_s = 0.1 * state.iteration;
      state.remaining_s = 0.1 * (state.max_iterations - state.iteration);
      progress(state);
      std::this_thread::sleep_for(std::chrono::milliseconds(100));
    }
    return results;
  };
  std::FILE* output = std::tmpfile();
  REQUIRE(output != nullptr);
  RunLoop::Options options;
  options.between_images = RunLoop::Options::BetweenImages::kNothing;
  options.output = output;
  options.progress_interval_s = 0.2;
  FrameListSource source(capture.frames);
  const RunLoop::Summary summary = RunLoop(options).Run(&source, &engine, hooks);
  CHECK(summary.end_s > 1.5);
  std::rewind(output);
  std::vector<std::string> lines;
  std::string line;
  for (int c; (c = std::fgetc(output)) != EOF;) {
    if (c != '\n') {
      line += char(c);
      continue;
    }
    lines.push_back(line);
    line.clear();
  }
  std::fclose(output);
  CHECK(line.empty());  // every line ended
  const std::regex image_line(R"(\[ *[0-9]+\] \S+ +(registered|pending|rejected) .*)");
  const std::regex end_line(
      R"(end: ([a-z ]+)(, [a-z0-9 ,]+)?; ([0-9]+\.[0-9]) s(, at most [0-9]+ s left)?)");
  int images = 0, adjustment_lines = 0;
  double last_elapsed = -1;
  for (const std::string& text : lines) {
    INFO(text);
    std::smatch match;
    if (std::regex_match(text, image_line)) {
      ++images;
    } else if (std::regex_match(text, match, end_line)) {
      const double elapsed = std::stod(match[3]);
      CHECK(elapsed >= last_elapsed);
      last_elapsed = elapsed;
      adjustment_lines += match[1] == "global adjustment";
    } else {
      CHECK((text.rfind("done: ", 0) == 0 || text.rfind("checkpoint: ", 0) == 0));
    }
  }
  // A result per image at least (an image of the initial pair waits first).
  CHECK(images >= int(capture.frames.size()));
  // Once at its start, then again after each 0.2 s of its 1.5 s.
  CHECK(adjustment_lines >= 5);
  CHECK(last_elapsed >= 1.5);
}

}  // namespace
}  // namespace flysfm
