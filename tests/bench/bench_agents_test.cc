// bench_agents as a process on its smallest ring (25 shots 7.5 deg apart with
// a gap of 180 deg, 0.3 MP): each run's figures agree with its shots'
// outcomes, and with what the scene's ground truth says of any engine.

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <set>
#include <string>

#include <catch2/catch.hpp>
#include <nlohmann/json.hpp>

#include "tests/testing/sanitizer.h"
#include "tests/testing/skip.h"
#include "tests/testing/temp_dir.h"

namespace flysfm {
namespace {

namespace fs = std::filesystem;

constexpr int kShots = 25;

// The benchmark's last line: its figures as JSON.
nlohmann::json RunBench(const fs::path& dir) {
  const fs::path output = dir / "output.txt";
  const std::string command = std::string(FLYSFM_BENCH_AGENTS) +
                              " --scenarios ring --photos " + std::to_string(kShots) +
                              " --gap-deg 180 --megapixels 0.3 --work " +
                              (dir / "photos").string() + " > " + output.string() + " 2>&1";
  const int status = std::system(command.c_str());
  std::ifstream in(output);
  std::string line, last;
  while (std::getline(in, line)) {
    if (!line.empty()) last = line;
  }
  INFO("bench_agents' last line: " << last);
  REQUIRE(status == 0);
  return nlohmann::json::parse(last);
}

// One run of the benchmark for every case, in `Dir()`.
const fs::path& Dir() {
  static const fs::path dir = testing::MakeTempDir("bench_agents");
  return dir;
}
const nlohmann::json& Bench() {
  static const nlohmann::json bench = RunBench(Dir());
  return bench;
}

void SkipUnderSanitizer() {
  if (testing::kSanitizerBuild) {
    // Four runs of the engine on 25 photos take minutes there; the engine's
    // own end-to-end tests run under the sanitizers.
    testing::SkipInThisBuild("a benchmark's run, too slow under a sanitizer");
  }
}

nlohmann::json ReadJson(const fs::path& path) {
  std::ifstream in(path);
  return nlohmann::json::parse(in);
}

TEST_CASE("bench_agents' ring: its counts are its shots' and the closed ring poses every shot") {
  SkipUnderSanitizer();
  const nlohmann::json& bench = Bench();
  const nlohmann::json& runs = bench.at("runs");
  // Each walk on the engine with sub-models, then on one model.
  REQUIRE(runs.size() == 4);
  for (int i = 0; i < 4; ++i) {
    CHECK(runs[i].at("scenario") == (i < 2 ? "ring forward" : "ring reversed"));
    CHECK(runs[i].at("engine") == (i % 2 == 0 ? "sub-models" : "one-model"));
  }
  for (int i = 0; i < 4; i += 2) {
    // A broken chain starts a sub-model instead of waiting: never fewer
    // shots posed at arrival than with one model, and, the walk going on
    // past the break, the sub-models merged by the end.
    CHECK(runs[i].at("posed_at_arrival").get<int>() >= runs[i + 1].at("posed_at_arrival").get<int>());
    // A link needs one shot posed in both sub-models when it sees points of
    // both, two when it does not (one fixes no scale): never a third.
    for (const nlohmann::json& delay : runs[i].at("merge_delays")) {
      CHECK(delay.at("linking_shots").get<int>() <= 2);
    }
  }
  for (const nlohmann::json& run : runs) {
    INFO(run.at("scenario").get<std::string>() + ", " + run.at("engine").get<std::string>());
    const nlohmann::json& shots = run.at("shot_outcomes");
    REQUIRE(run.at("shots") == kShots);
    REQUIRE(shots.size() == std::size_t(kShots));
    // Every photo once, in the order walked.
    std::vector<std::string> names;
    for (const nlohmann::json& shot : shots) names.push_back(shot.at("name"));
    CHECK(std::set<std::string>(names.begin(), names.end()).size() == std::size_t(kShots));
    if (run.at("scenario") == "ring forward") {
      CHECK(std::is_sorted(names.begin(), names.end()));
    } else {
      CHECK(std::is_sorted(names.rbegin(), names.rend()));
    }
    // The counts are those of the shots' outcomes.
    int at_arrival = 0, at_end = 0, unposed = 0, longest = 0, partnered = 0, partnered_posed = 0;
    for (const nlohmann::json& shot : shots) {
      const bool posed = shot.at("posed_at_arrival");
      at_arrival += posed;
      partnered += shot.at("has_partner").get<bool>();
      partnered_posed += posed && shot.at("has_partner").get<bool>();
      at_end += shot.at("posed_at_end").get<bool>();
      unposed = posed ? 0 : unposed + 1;
      longest = std::max(longest, unposed);
      // A pose at arrival has an error at arrival, and only then.
      CHECK((shot.at("error_at_arrival_m").get<double>() >= 0) == posed);
    }
    CHECK(run.at("posed_at_arrival") == at_arrival);
    CHECK(run.at("posed_at_end") == at_end);
    CHECK(run.at("longest_unposed_at_arrival") == longest);
    CHECK(run.at("with_partner_posed_at_arrival") == partnered_posed);
    // Every shot has an earlier neighbour on the ring within 1.5 steps but
    // the first and the first past the gap (180 deg, 24 steps, away from
    // every earlier shot), whichever way the ring is walked.
    CHECK_FALSE(shots[0].at("has_partner").get<bool>());
    CHECK(run.at("with_partner") == kShots - 2);
    CHECK(partnered == kShots - 2);
    REQUIRE(run.at("sources").size() == 1);
    CHECK(run.at("sources")[0].at("posed_at_arrival") == at_arrival);
    // No engine poses the first photo alone.
    CHECK_FALSE(shots[0].at("posed_at_arrival").get<bool>());
    // Each shot overlaps its neighbours on the ring but across the gap, so
    // by the end every one has a pose, none of them wrong, and the centres
    // are those of the ground truth to far better than the wrong bound
    // (5 % of the 40 m ring; 0.3 MP photos give a few millimetres).
    CHECK(run.at("posed_at_end") == kShots);
    CHECK(run.at("wrong_at_arrival") == 0);
    CHECK(run.at("wrong_at_end") == 0);
    CHECK(run.at("scene_size_m").get<double>() == Approx(40.0).margin(1.5));
    CHECK(run.at("center_rmse_m").get<double>() < 0.002 * run.at("scene_size_m").get<double>());
    CHECK(run.at("models") == 1);
  }
}

TEST_CASE("A restart continues every sub-model: the ring resumed after its break merges as fed whole") {
  SkipUnderSanitizer();
  const nlohmann::json& bench = Bench();
  // The forward ring's photos as a photographer's folder.
  const fs::path shots = Dir() / "folder";
  fs::create_directories(shots);
  for (const fs::directory_entry& entry : fs::directory_iterator(Dir() / "photos" / "ring" / "shots")) {
    if (entry.path().extension() == ".jpg") fs::copy_file(entry.path(), shots / entry.path().filename());
  }
  const fs::path out = Dir() / "out";
  const std::string batch = std::string(FLYSFM_BINARY) + " batch " + shots.string() +
                            " --camera \"" + bench.at("camera").get<std::string>() +
                            "\" --out " + out.string();
  // Stopped after 15 shots, past the break: two sub-models are checkpointed.
  REQUIRE(std::system((batch + " --max-images 15 > " + (Dir() / "first.txt").string() +
                       " 2>&1").c_str()) == 0);
  const nlohmann::json first = ReadJson(out / "summary.json");
  REQUIRE(first.at("models").size() >= 2);
  REQUIRE(std::system((batch + " --resume > " + (Dir() / "second.txt").string() + " 2>&1")
                          .c_str()) == 0);
  const nlohmann::json second = ReadJson(out / "summary.json");
  // Resumed, every shot is posed and the sub-models merged, as in the
  // uninterrupted run (the benchmark's first).
  const nlohmann::json& whole = bench.at("runs")[0];
  CHECK(second.at("registered") == whole.at("posed_at_end"));
  CHECK(second.at("models").size() == std::size_t(whole.at("models").get<int>()));
  CHECK(second.at("resumed_images") == 15);
  std::ifstream log(out / "log.jsonl");
  int merges = 0;
  for (std::string line; std::getline(log, line);) {
    merges += nlohmann::json::parse(line).value("merged_models", 0);
  }
  CHECK(merges >= 1);
}

}  // namespace
}  // namespace flysfm
