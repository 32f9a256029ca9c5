// Does every shot get a pose when it arrives? A shot that does not connect
// to the model starts a sub-model with a waiting shot it pairs with, and the
// sub-models merge when a later shot links them (Engine, SubModelOptions);
// with one model (sub-models off) it waits in the pending pool, without a
// pose, until a later shot bridges the gap. This benchmark measures that on
// rendered captures of bench_photos' building (exact ground truth) and on
// real sets with their ground-truth cameras:
//
//   ring     one photographer walks a ring of shots around the building, one
//            step of which is a gap (--gap-deg, 60 by default, across the
//            south-east corner) too wide to match across; the ring walked
//            forward and reversed (two runs on the same photos).
//   agents   three photographers start on three sides and each walks about
//            140 deg around, their shots interleaved by capture time through
//            MergedSource, each frame tagged with its photographer.
//   two      two photographers start on opposite sides and each walks half
//            way round: each comes near where the other started only
//            at the end of its walk.
//   fountain, temple   fountain-P11 (11 photos) and templeRing (19) of
//            --data split between two photographers starting at the set's
//            two ends and walking towards each other, interleaved.
//
//   bench_agents [--scenarios ring,agents,two,fountain,temple]
//                [--engines sub-models,one-model,one-photographer]
//                [--photos N] [--walk-photos N] [--gap-deg D]
//                [--megapixels MP] [--seed S] [--supersampling K] [--work DIR]
//                [--data DIR] [--glibc-malloc-defaults]
//
// Each scenario runs on each engine: with sub-models; with one model; and
// (several photographers only) with sub-models on the same shots fed by one
// photographer walking the whole path from one end, the accuracy several
// photographers must keep. --photos is the ring's number of shots; the step
// between two shots, (360 - gap) / (photos - 1) degrees, is every walk's
// unless --walk-photos gives the number of each agents and two walk's shots.
// The engine is given the true K and is fed as `flysfm batch` feeds it,
// unpaced (nothing refined between shots, so the figures do not depend on
// the machine's speed). For each run it prints one line per shot and then:
// the shots; how many had a pose at their arrival (the shot's own result of
// its own engine call), and how many of those with an initial partner (a
// shot arrived before it within 1.5 steps along the path: one that the
// first initialisation could pair it with); how many at the end (after
// Finish); the longest stretch of consecutive shots without a pose at
// arrival; the same per photographer; the camera-centre RMSE after Sim3 of
// the final model and of the poses as they were at arrival (each sub-model
// aligned on its own, in the frame it had then); how many poses are wrong (a
// centre off by more than 5 % of the scene, the largest distance between two
// true camera centres); the per-shot time of all stages; the merges, each
// with the shots it waited for and its time; and the number of sub-models at
// the end. Ends with one line of JSON.

#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <map>
#include <memory>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include "bench/bench_session.h"
#include "bench/photo_session.h"
#include "core/engine.h"
#include "core/malloc_policy.h"
#include "geometry/statistics.h"
#include "io/evaluation/evaluation.h"
#include "io/sources/image_source.h"
#include "io/sources/merged_source.h"
#include "tests/testing/datasets.h"

namespace flysfm {
namespace {

namespace fs = std::filesystem;

struct Flags {
  std::vector<std::string> scenarios = {"ring", "agents", "two", "fountain", "temple"};
  int num_photos = 41;
  int walk_photos = 0;
  double gap_deg = 60;
  double megapixels = 6;
  int seed = 1;
  int supersampling = 1;
  std::string work;
  std::string data;
  bool glibc_malloc_defaults = false;
  // Each scenario runs on each: the engine with sub-models; with one model
  // (SubModelOptions::enabled false), the figure it improves on; and the
  // same shots fed by one photographer in the order of their path, the
  // accuracy several photographers must keep.
  std::vector<std::string> engines = {"sub-models", "one-model", "one-photographer"};
};

// The south-east corner's direction from the building's centre (16 m x
// 12 m): the ring's gap is centred on it, so that the shots on either side
// see the east wall from 60 deg apart, one of them at a grazing angle.
// Centred on a wall's normal instead, both would see that wall 30 deg off
// its normal, close enough to match.
const double kGapCentreDeg = -std::atan2(6.0, 8.0) * 180 / M_PI;

// A shot has an initial partner at its arrival when a shot that arrived
// before it lies within this many steps along the path: consecutive shots
// of a walk are one step apart and overlap; a gap's two sides lie several
// steps apart.
constexpr double kPartnerSteps = 1.5;

// One photographer of a rendered scenario: where each shot is taken and
// when.
struct Photographer {
  std::string tag;               // empty for a lone photographer
  std::vector<RingStop> stops;   // in the order they are shot
  std::vector<double> capture_s;
};

// A run of the engine on one scenario's photographers: rendered walks
// around bench_photos' building, or a real photo set of --data split
// between two photographers.
struct Scenario {
  std::string name;
  std::string folder;  // under the work folder; a photographer's photos in <folder>/<tag>
  std::vector<Photographer> photographers;
  double step_deg = 0;    // between a walk's consecutive shots
  std::string photo_set;  // fountain, temple: a real set instead of renders
};

double StepDeg(const Flags& flags) { return (360.0 - flags.gap_deg) / (flags.num_photos - 1); }

std::string ShotName(int index) {
  char name[32];
  std::snprintf(name, sizeof(name), "shot_%04d.jpg", index);
  return name;
}

// A photographer walking counter-clockwise from `start_deg`, `num_shots`
// shots `step_deg` apart, one every `interval_s` from `first_s`.
Photographer Walk(const std::string& tag, double start_deg, double step_deg, int num_shots,
                  double radius_m, double height_m, double first_s, double interval_s) {
  Photographer walker;
  walker.tag = tag;
  for (int i = 0; i < num_shots; ++i) {
    walker.stops.push_back({ShotName(i), start_deg + i * step_deg, radius_m, height_m});
    walker.capture_s.push_back(first_s + i * interval_s);
  }
  return walker;
}

// The ring: shots `step` apart all round but for one gap after the first
// third, centred on the south-east corner; the last shot is one step before
// the first, so that walking on closes the ring.
std::vector<Scenario> RingScenarios(const Flags& flags) {
  const double step = StepDeg(flags);
  const int before_gap = (flags.num_photos - 1) / 3;  // the last shot before it
  const double start = kGapCentreDeg - 0.5 * flags.gap_deg - before_gap * step;
  Photographer forward;
  for (int i = 0; i < flags.num_photos; ++i) {
    const double angle = start + i * step + (i > before_gap ? flags.gap_deg - step : 0.0);
    forward.stops.push_back({ShotName(i), angle, 20.0, 1.6});
    forward.capture_s.push_back(10.0 * i);
  }
  Photographer reversed = forward;
  std::reverse(reversed.stops.begin(), reversed.stops.end());
  return {{"ring forward", "ring", {forward}, step, ""},
          {"ring reversed", "ring", {reversed}, step, ""}};
}

// The step of a walk of `arc_deg` in --walk-photos shots (`shots_in_arc`
// of them for `arc_deg`), else the ring's.
double WalkStepDeg(const Flags& flags, double arc_deg, int shots_in_arc) {
  return flags.walk_photos > 0 ? arc_deg / shots_in_arc : StepDeg(flags);
}

// Three photographers starting 120 deg apart (south, north-east, north-west
// of the building), each walking about 140 deg: each reaches where the next
// one started. Their paces differ (10, 11 and 9 s), as three people's do.
Scenario AgentsScenario(const Flags& flags) {
  const double step = WalkStepDeg(flags, 140.0, flags.walk_photos - 1);
  const int shots = int(std::lround(140.0 / step)) + 1;
  return {"agents",
          "agents",
          {Walk("A", -90.0, step, shots, 20.0, 1.6, 0.0, 10.0),
           Walk("B", 30.0, step, shots, 21.0, 1.7, 2.0, 11.0),
           Walk("C", 150.0, step, shots, 19.0, 1.5, 5.0, 9.0)},
          step,
          ""};
}

// Two photographers starting on opposite sides (west and east), each
// walking half way round at the same pace: the first shots of each are next
// to the last shots of the other, so they meet only towards the end.
Scenario TwoScenario(const Flags& flags) {
  const double step = WalkStepDeg(flags, 180.0, flags.walk_photos);
  const int shots = int(std::lround(180.0 / step));
  return {"two",
          "two",
          {Walk("A", 180.0, step, shots, 20.0, 1.6, 0.0, 10.0),
           Walk("B", 0.0, step, shots, 20.0, 1.7, 5.0, 10.0)},
          step,
          ""};
}

// The width of a 3:2 photo of `megapixels` (6 MP is 3000 x 2000, as
// bench_photos').
int PhotoWidth(double megapixels) { return int(std::lround(std::sqrt(megapixels * 1e6 * 1.5))); }

// Where `walker`'s photos are rendered.
fs::path WalkerFolder(const fs::path& work, const Scenario& scenario,
                      const Photographer& walker) {
  return work / scenario.folder / (walker.tag.empty() ? "shots" : walker.tag);
}

// Renders what is missing of `walker`'s photos; returns the true camera
// centres by file name. The stops are taken in name order whatever order a
// run walks them in, so that the forward and reversed rings share the
// photos and the hand's jitter.
std::map<std::string, Eigen::Vector3d> RenderWalker(const Flags& flags, const fs::path& dir,
                                                    const Camera& camera,
                                                    const Photographer& walker,
                                                    std::vector<double>* render_ms) {
  std::vector<RingStop> stops = walker.stops;
  std::sort(stops.begin(), stops.end(),
            [](const RingStop& a, const RingStop& b) { return a.name < b.name; });
  // The plan: every stop, so that a folder rendered for other parameters is
  // never reused.
  std::ostringstream plan;
  plan.precision(9);
  for (const RingStop& stop : stops) {
    plan << stop.name << ' ' << stop.angle_deg << ' ' << stop.radius_m << ' ' << stop.height_m
         << ';';
  }
  PrepareRenderFolder(dir, std::uint32_t(flags.seed), camera, flags.supersampling, plan.str());
  // Each photographer's jitter seeded apart.
  std::uint32_t seed = std::uint32_t(flags.seed);
  for (const char c : walker.tag) seed = seed * 131u + std::uint32_t(c);
  const std::vector<Shot> shots = MakeRingShots(stops, seed);
  const std::vector<double> times =
      RenderPhotoSession(shots, camera, std::uint32_t(flags.seed), flags.supersampling, dir, 2);
  render_ms->insert(render_ms->end(), times.begin(), times.end());
  std::map<std::string, Eigen::Vector3d> centres;
  for (const Shot& shot : shots) centres[shot.name] = ProjectionCenter(shot.cam_from_world);
  return centres;
}

// A shot as a run feeds it, and where it lies along the path every shot of
// the scenario lies on (in steps: a walk's consecutive shots are one apart).
struct FedShot {
  Frame frame;  // named by the photographer's file name
  double position = 0;
};
struct FedPhotographer {
  std::string tag;
  std::vector<FedShot> shots;  // in the order shot
};
// What a scenario feeds the engine, and the truth it is measured against.
struct Feed {
  std::string camera;  // as --camera takes it
  std::vector<FedPhotographer> photographers;
  std::map<std::string, Eigen::Vector3d> truth;  // by run name
  double period = 0;  // positions repeat after this many steps (a ring); 0: never
};

// The name a shot has in the run: MergedSource names a frame `<tag>/<name>`
// when it merges more than one photographer.
std::string RunName(const Feed& feed, const std::string& tag, const std::string& file) {
  return feed.photographers.size() > 1 ? tag + "/" + file : file;
}

// Renders the scenario's photos (what is missing) and feeds them.
Feed RenderedFeed(const Flags& flags, const fs::path& work, const Scenario& scenario,
                  const std::string& camera_text) {
  const int width = PhotoWidth(flags.megapixels);
  const Camera camera = Camera::FromString(camera_text, width, width * 2 / 3);
  Feed feed;
  feed.camera = camera_text;
  feed.period = 360.0 / scenario.step_deg;
  std::vector<double> render_ms;
  for (const Photographer& walker : scenario.photographers) {
    feed.photographers.push_back({walker.tag, {}});
  }
  for (std::size_t p = 0; p < scenario.photographers.size(); ++p) {
    const Photographer& walker = scenario.photographers[p];
    const fs::path dir = WalkerFolder(work, scenario, walker);
    const std::map<std::string, Eigen::Vector3d> centres =
        RenderWalker(flags, dir, camera, walker, &render_ms);
    for (std::size_t i = 0; i < walker.stops.size(); ++i) {
      FedShot shot;
      shot.frame.name = walker.stops[i].name;
      shot.frame.path = dir / shot.frame.name;
      shot.frame.timestamp = walker.capture_s[i];
      shot.position = walker.stops[i].angle_deg / scenario.step_deg;
      feed.photographers[p].shots.push_back(shot);
      feed.truth[RunName(feed, walker.tag, shot.frame.name)] = centres.at(shot.frame.name);
    }
  }
  if (!render_ms.empty()) {
    std::printf("render: %zu photos rendered (median %.0f ms each, one core), the others "
                "reused\n",
                render_ms.size(), Median(render_ms));
  }
  return feed;
}

// A real set split between two photographers starting at its two ends and
// walking towards each other at the same pace, interleaved: A shoots the
// first half in the set's order, B the rest from the last image back.
Feed PhotoSetFeed(const testing::PhotoSet& set) {
  Feed feed;
  feed.camera = set.camera;
  feed.photographers = {{"A", {}}, {"B", {}}};
  const std::size_t half = (set.frames.size() + 1) / 2;
  for (std::size_t i = 0; i < set.frames.size(); ++i) {
    const bool first_half = i < half;
    FedPhotographer& walker = feed.photographers[first_half ? 0 : 1];
    FedShot shot;
    shot.frame = set.frames[i];
    shot.position = double(i);
    walker.shots.push_back(shot);
  }
  std::reverse(feed.photographers[1].shots.begin(), feed.photographers[1].shots.end());
  const std::map<std::string, Eigen::Vector3d> centres = set.Centres();
  for (FedPhotographer& walker : feed.photographers) {
    for (std::size_t i = 0; i < walker.shots.size(); ++i) {
      walker.shots[i].frame.timestamp = 10.0 * double(i) + (walker.tag == "B" ? 5.0 : 0.0);
      feed.truth[RunName(feed, walker.tag, walker.shots[i].frame.name)] =
          centres.at(walker.shots[i].frame.name);
    }
  }
  return feed;
}

// The same shots fed by one photographer walking the scenario's path from
// one end to the other (each named as in the several photographers' run).
Feed OnePhotographerFeed(const Feed& feed) {
  Feed one = feed;
  one.photographers = {{"", {}}};
  for (const FedPhotographer& walker : feed.photographers) {
    for (FedShot shot : walker.shots) {
      shot.frame.name = RunName(feed, walker.tag, shot.frame.name);
      one.photographers[0].shots.push_back(shot);
    }
  }
  std::vector<FedShot>& shots = one.photographers[0].shots;
  std::stable_sort(shots.begin(), shots.end(), [](const FedShot& a, const FedShot& b) {
    return a.position < b.position;
  });
  for (std::size_t i = 0; i < shots.size(); ++i) shots[i].frame.timestamp = 10.0 * double(i);
  return one;
}

// Whether a shot at `position` has a partner among the positions of the
// shots that arrived before it.
bool HasPartner(double position, const std::vector<double>& earlier, double period) {
  return std::any_of(earlier.begin(), earlier.end(), [&](double other) {
    double distance = std::abs(position - other);
    if (period > 0) distance = std::min(std::fmod(distance, period),
                                        period - std::fmod(distance, period));
    return distance <= kPartnerSteps;
  });
}

// What a shot got.
struct ShotOutcome {
  std::string name;
  std::string source;  // the photographer's tag
  bool has_partner = false;  // an earlier shot within kPartnerSteps
  bool posed_at_arrival = false;
  bool posed_at_end = false;
  std::optional<Eigen::Vector3d> centre_at_arrival;
  std::optional<double> error_at_arrival_m;  // after the arrival poses' Sim3
  std::optional<double> error_at_end_m;      // after the final model's Sim3
  double all_stages_ms = 0;
  bool posed_in_others = false;  // in another sub-model than its own
  int merged_models = 0;
  double merge_ms = 0;
};

// For each merge: the shots that arrived from the first one posed in two
// sub-models since the last merge to the one that merged them, both counted
// (1: the first merged them), and how many of those were posed in two.
struct MergeDelay {
  int arrivals = 0;
  int linking_shots = 0;
};
std::vector<MergeDelay> MergeDelays(const std::vector<ShotOutcome>& shots) {
  std::vector<MergeDelay> delays;
  std::optional<std::size_t> first_link;
  int linking = 0;
  for (std::size_t i = 0; i < shots.size(); ++i) {
    if (shots[i].posed_in_others) {
      if (!first_link) first_link = i;
      ++linking;
    }
    if (shots[i].merged_models > 0) {
      delays.push_back({first_link ? int(i - *first_link) + 1 : 1, std::max(linking, 1)});
      first_link.reset();
      linking = 0;
    }
  }
  return delays;
}

// The counts of a set of shots in arrival order (a run's or a photographer's).
struct Counts {
  int shots = 0;
  int posed_at_arrival = 0;
  int with_partner = 0;            // shots with an initial partner at arrival
  int with_partner_posed = 0;      // ... posed at arrival
  int posed_at_end = 0;
  int longest_unposed = 0;  // consecutive shots without a pose at arrival
  int wrong_at_arrival = 0;
  int wrong_at_end = 0;
  double rmse_at_end_m = -1;      // over the shots posed at the end
  double rmse_at_arrival_m = -1;  // over the shots posed at arrival
};

double Rms(const std::vector<double>& values) {
  if (values.empty()) return -1;
  double sum = 0;
  for (const double v : values) sum += v * v;
  return std::sqrt(sum / values.size());
}

Counts Count(const std::vector<const ShotOutcome*>& shots, double wrong_m) {
  Counts counts;
  int unposed = 0;
  std::vector<double> at_end, at_arrival;
  for (const ShotOutcome* shot : shots) {
    ++counts.shots;
    counts.posed_at_arrival += shot->posed_at_arrival;
    counts.with_partner += shot->has_partner;
    counts.with_partner_posed += shot->has_partner && shot->posed_at_arrival;
    counts.posed_at_end += shot->posed_at_end;
    unposed = shot->posed_at_arrival ? 0 : unposed + 1;
    counts.longest_unposed = std::max(counts.longest_unposed, unposed);
    if (shot->error_at_arrival_m) {
      at_arrival.push_back(*shot->error_at_arrival_m);
      counts.wrong_at_arrival += *shot->error_at_arrival_m > wrong_m;
    }
    if (shot->error_at_end_m) {
      at_end.push_back(*shot->error_at_end_m);
      counts.wrong_at_end += *shot->error_at_end_m > wrong_m;
    }
  }
  counts.rmse_at_end_m = Rms(at_end);
  counts.rmse_at_arrival_m = Rms(at_arrival);
  return counts;
}

nlohmann::json CountsJson(const Counts& counts) {
  return {{"shots", counts.shots},
          {"posed_at_arrival", counts.posed_at_arrival},
          {"with_partner", counts.with_partner},
          {"with_partner_posed_at_arrival", counts.with_partner_posed},
          {"posed_at_end", counts.posed_at_end},
          {"longest_unposed_at_arrival", counts.longest_unposed},
          {"wrong_at_arrival", counts.wrong_at_arrival},
          {"wrong_at_end", counts.wrong_at_end},
          {"center_rmse_m", counts.rmse_at_end_m},
          {"arrival_center_rmse_m", counts.rmse_at_arrival_m}};
}

void PrintCounts(const char* label, const Counts& counts) {
  std::printf("  %-12s %3d shots: %3d posed at arrival (%d of the %d with an initial "
              "partner), %3d at the end; longest stretch "
              "without a pose at arrival %3d; wrong at arrival %d, at the end %d; centre RMSE "
              "%.2f mm (at the end), %.2f mm (at arrival)\n",
              label, counts.shots, counts.posed_at_arrival, counts.with_partner_posed,
              counts.with_partner, counts.posed_at_end,
              counts.longest_unposed, counts.wrong_at_arrival, counts.wrong_at_end,
              1000 * counts.rmse_at_end_m, 1000 * counts.rmse_at_arrival_m);
}

// A shot's camera centre and the sub-model whose frame it is in.
struct PosedCentre {
  model_t model_id = kInvalidModelId;
  Eigen::Vector3d centre;
};

// Each shot's centre error after the Sim3 of its sub-model's centres onto
// the truth (a sub-model keeps its frame until it merges into another, whose
// frame then holds both); a sub-model of fewer than three shots fixes no Sim3
// and gives no errors. Returns the shots compared.
int SetErrors(const std::map<std::string, PosedCentre>& estimated,
              const std::map<std::string, Eigen::Vector3d>& truth,
              std::optional<double> ShotOutcome::*error, std::vector<ShotOutcome>* shots) {
  std::map<model_t, std::vector<std::string>> names_of;
  for (const auto& [name, posed] : estimated) names_of[posed.model_id].push_back(name);
  int compared = 0;
  for (const auto& [model_id, names] : names_of) {
    std::vector<Eigen::Vector3d> centres, reference;
    for (const std::string& name : names) {
      centres.push_back(estimated.at(name).centre);
      reference.push_back(truth.at(name));
    }
    const std::optional<PositionErrors> errors = ComparePositionsAfterSim3(centres, reference);
    if (!errors) continue;
    compared += errors->num_compared;
    for (ShotOutcome& shot : *shots) {
      const auto it = estimated.find(shot.name);
      if (it == estimated.end() || it->second.model_id != model_id) continue;
      shot.*error =
          (errors->reference_from_estimate * it->second.centre - truth.at(shot.name)).norm();
    }
  }
  return compared;
}

double SceneSize(const std::map<std::string, Eigen::Vector3d>& truth) {
  double size = 0;
  for (const auto& [a, pa] : truth) {
    for (const auto& [b, pb] : truth) size = std::max(size, (pa - pb).norm());
  }
  return size;
}

nlohmann::json RunScenario(const std::string& scenario_name, const Feed& feed,
                           const std::string& engine_name) {
  // Each photographer's frames, named as the run names them.
  std::map<std::string, std::string> source_of;
  std::map<std::string, double> position_of;
  std::vector<std::unique_ptr<FrameListSource>> lists;
  std::vector<MergedSource::Input> inputs;
  std::vector<std::string> tags;
  for (const FedPhotographer& walker : feed.photographers) {
    std::vector<Frame> frames;
    for (const FedShot& shot : walker.shots) {
      frames.push_back(shot.frame);
      const std::string name = RunName(feed, walker.tag, shot.frame.name);
      source_of[name] = walker.tag;
      position_of[name] = shot.position;
    }
    lists.push_back(std::make_unique<FrameListSource>(std::move(frames)));
    inputs.push_back({walker.tag.empty() ? "shots" : walker.tag, lists.back().get()});
    if (feed.photographers.size() > 1) tags.push_back(walker.tag);
  }
  const std::map<std::string, Eigen::Vector3d>& truth = feed.truth;
  MergedSourceOptions merge;
  merge.order = MergedSourceOptions::Order::kCaptureTime;
  MergedSource source(inputs, merge);

  std::printf("\n%s, %s: %zu photographer%s, %zu shots\n", scenario_name.c_str(),
              engine_name.c_str(), feed.photographers.size(),
              feed.photographers.size() > 1 ? "s" : "", truth.size());
  std::fflush(stdout);
  Engine::Options engine_options;
  engine_options.sub_models.enabled = engine_name != "one-model";
  Engine engine(engine_options, Camera::FromString(feed.camera, 0, 0));
  bench::SessionOptions options;
  options.run.print = false;
  options.run.between_images = RunLoop::Options::BetweenImages::kNothing;
  options.run.sources = tags;
  int index = 0;
  options.on_image = [&](const Engine&, const std::vector<ImageResult>& out,
                         const StageTimes& times, double engine_ms) {
    // The engine call's other results are waiting shots it let register.
    const std::string model =
        out.front().model_id == kInvalidModelId ? "" : " in " + std::to_string(out.front().model_id);
    const std::string posed_in_others =
        out.front().num_posed_in_others > 0
            ? ", posed in " + std::to_string(out.front().num_posed_in_others) + " other"
            : "";
    const std::string merged =
        out.front().num_merged_models > 0
            ? ", merged " + std::to_string(out.front().num_merged_models) + " (" +
                  std::to_string(int(std::lround(out.front().times.merge))) + " ms)"
            : "";
    std::printf("[%4d] %-22s %-10s all stages %6.0f ms, engine %6.0f ms, %2d/%2d pairs, "
                "model %d img in %d sub-model(s)%s%s%s, %zu waiting registered with it\n",
                ++index, out.front().name.c_str(), ImageStatusName(out.front().status),
                times.total, engine_ms, out.front().num_verified_pairs,
                out.front().num_candidates, out.back().model_images, out.back().num_models,
                model.c_str(), posed_in_others.c_str(), merged.c_str(), out.size() - 1);
    std::fflush(stdout);
  };
  const bench::Session session = bench::RunSession(&engine, &source, options);

  // Each shot's outcome, in arrival order.
  std::vector<ShotOutcome> shots;
  std::map<std::string, std::size_t> shot_index;
  for (std::size_t i = 0; i < session.run.calls.size(); ++i) {
    ShotOutcome shot;
    shot.name = session.run.calls[i].name;
    shot.source = source_of.at(shot.name);
    shot.all_stages_ms = i < session.all_stages_ms.size() ? session.all_stages_ms[i] : 0;
    shot_index[shot.name] = shots.size();
    shots.push_back(shot);
  }
  std::vector<double> arrived;
  for (ShotOutcome& shot : shots) {
    const double position = position_of.at(shot.name);
    shot.has_partner = HasPartner(position, arrived, feed.period);
    arrived.push_back(position);
  }
  std::map<std::string, PosedCentre> at_arrival;
  for (const RunLoop::Reported& reported : session.run.results) {
    ShotOutcome& outcome = shots.at(shot_index.at(reported.result.name));
    outcome.posed_in_others |= reported.result.num_posed_in_others > 0;
    outcome.merged_models += reported.result.num_merged_models;
    outcome.merge_ms += reported.result.times.merge;
    if (!reported.arriving_image || reported.result.status != ImageStatus::kRegistered) continue;
    ShotOutcome& shot = shots.at(shot_index.at(reported.result.name));
    shot.posed_at_arrival = true;
    at_arrival[shot.name] = {reported.result.model_id,
                             ProjectionCenter(*reported.result.cam_from_world)};
  }
  const Reconstruction& model = engine.reconstruction();
  std::map<std::string, PosedCentre> at_end;
  for (const auto& [id, image] : model.images()) {
    if (!image.IsRegistered() || !shot_index.count(image.name)) continue;
    shots[shot_index.at(image.name)].posed_at_end = true;
    at_end[image.name] = {image.model_id, ProjectionCenter(*image.cam_from_world)};
  }
  const int compared_at_end = SetErrors(at_end, truth, &ShotOutcome::error_at_end_m, &shots);
  SetErrors(at_arrival, truth, &ShotOutcome::error_at_arrival_m, &shots);

  const double scene_size = SceneSize(truth);
  const double wrong_m = 0.05 * scene_size;
  std::vector<const ShotOutcome*> all;
  for (const ShotOutcome& shot : shots) all.push_back(&shot);
  const Counts counts = Count(all, wrong_m);
  const int models = int(model.Models().size());
  const double median_ms = Median(session.all_stages_ms);

  std::printf("\n%s: %d shots, %d posed at arrival, %d at the end (%zu in the model, %zu "
              "pending); longest stretch without a pose at arrival %d; wrong (centre off by "
              "more than 5 %% of the scene, %.2f m of %.1f m) at arrival %d, at the end %d; "
              "centre RMSE after Sim3 %.2f mm at the end (%d compared), %.2f mm at arrival; "
              "all stages median %.0f ms per shot; sub-models at the end %d\n",
              scenario_name.c_str(), counts.shots, counts.posed_at_arrival, counts.posed_at_end,
              model.NumRegisteredImages(), engine.PendingImageNames().size(),
              counts.longest_unposed, wrong_m, scene_size, counts.wrong_at_arrival,
              counts.wrong_at_end, 1000 * counts.rmse_at_end_m,
              compared_at_end, 1000 * counts.rmse_at_arrival_m,
              median_ms, models);
  nlohmann::json sources = nlohmann::json::array();
  for (const FedPhotographer& walker : feed.photographers) {
    std::vector<const ShotOutcome*> own;
    for (const ShotOutcome& shot : shots) {
      if (shot.source == walker.tag) own.push_back(&shot);
    }
    const Counts walker_counts = Count(own, wrong_m);
    const std::string label = walker.tag.empty() ? "photographer" : "source " + walker.tag;
    PrintCounts(label.c_str(), walker_counts);
    nlohmann::json json = CountsJson(walker_counts);
    json["source"] = walker.tag;
    sources.push_back(json);
  }
  bench::PrintSessionFigures(session, ("  " + scenario_name).c_str());

  // Each shot in arrival order: what a script needs to see where the
  // stretches without a pose fall.
  nlohmann::json shot_list = nlohmann::json::array();
  for (const ShotOutcome& shot : shots) {
    shot_list.push_back({{"name", shot.name},
                         {"source", shot.source},
                         {"has_partner", shot.has_partner},
                         {"posed_at_arrival", shot.posed_at_arrival},
                         {"posed_at_end", shot.posed_at_end},
                         {"error_at_arrival_m", shot.error_at_arrival_m.value_or(-1.0)},
                         {"error_at_end_m", shot.error_at_end_m.value_or(-1.0)},
                         {"posed_in_other_models", shot.posed_in_others},
                         {"merged_models", shot.merged_models},
                         {"merge_ms", shot.merge_ms}});
  }
  const std::vector<MergeDelay> merge_delays = MergeDelays(shots);
  double max_merge_ms = 0;
  for (const ShotOutcome& shot : shots) max_merge_ms = std::max(max_merge_ms, shot.merge_ms);
  std::string delays_text;
  nlohmann::json delays_json = nlohmann::json::array();
  for (const MergeDelay& delay : merge_delays) {
    delays_text += (delays_text.empty() ? "" : ", ") + std::to_string(delay.linking_shots) +
                   " (" + std::to_string(delay.arrivals) + ")";
    delays_json.push_back({{"linking_shots", delay.linking_shots}, {"arrivals", delay.arrivals}});
  }
  std::printf("  %s: %zu merge(s), each at this many shots posed in two sub-models (shots "
              "arrived since the first of them): %s; the longest merge %.0f ms\n",
              scenario_name.c_str(), merge_delays.size(),
              delays_text.empty() ? "-" : delays_text.c_str(), max_merge_ms);
  nlohmann::json json = CountsJson(counts);
  json.update({{"scenario", scenario_name},
               {"engine", engine_name},
               {"merge_delays", delays_json},
               {"max_merge_ms", max_merge_ms},
               {"photographers", feed.photographers.size()},
               {"models", models},
               {"scene_size_m", scene_size},
               {"wrong_threshold_m", wrong_m},
               {"compared_at_end", compared_at_end},
               {"all_stages_median_ms", median_ms},
               {"sources", sources},
               {"shot_outcomes", shot_list},
               {"session", bench::SessionJson(session)}});
  return json;
}

int Main(const Flags& flags) {
  // As flysfm, before any thread starts: the engine as it runs there.
  const bool malloc_policy = !flags.glibc_malloc_defaults && ApplyMallocPolicy();
  const fs::path work = !flags.work.empty()
                            ? fs::path(flags.work)
                            : fs::temp_directory_path() /
                                  ("bench_agents_" + std::to_string(::getpid()));
  const int width = PhotoWidth(flags.megapixels);
  const std::string camera_text = PhotoSessionCamera(width);
  const Camera camera = Camera::FromString(camera_text, width, width * 2 / 3);
  std::printf("bench_agents: %s; K given (%s, %dx%d); ring of %d shots %.2f deg apart with a "
              "gap of %.0f deg; seed %d; photos in %s\n",
              [&] {
                std::string list;
                for (const std::string& s : flags.scenarios) list += (list.empty() ? "" : ",") + s;
                return list;
              }()
                  .c_str(),
              camera_text.c_str(), camera.width, camera.height, flags.num_photos,
              StepDeg(flags), flags.gap_deg, flags.seed, work.c_str());
  std::fflush(stdout);
  std::vector<Scenario> scenarios;
  for (const std::string& name : flags.scenarios) {
    if (name == "ring") {
      for (Scenario& ring : RingScenarios(flags)) scenarios.push_back(std::move(ring));
    } else if (name == "agents") {
      scenarios.push_back(AgentsScenario(flags));
    } else if (name == "two") {
      scenarios.push_back(TwoScenario(flags));
    } else {
      scenarios.push_back({name == "fountain" ? "fountain-P11" : "templeRing", name, {}, 0, name});
    }
  }
  nlohmann::json runs = nlohmann::json::array();
  for (const Scenario& scenario : scenarios) {
    Feed feed;
    if (scenario.photo_set.empty()) {
      feed = RenderedFeed(flags, work, scenario, camera_text);
    } else {
      const fs::path data = flags.data;
      try {
        feed = PhotoSetFeed(scenario.photo_set == "fountain" ? testing::FountainP11(data)
                                                             : testing::TempleRing19(data));
      } catch (const std::exception& error) {
        std::printf("\n%s: skipped, its data cannot be read: %s\n", scenario.name.c_str(),
                    error.what());
        continue;
      }
    }
    std::map<std::string, double> rmse_of;
    for (const std::string& engine_name : flags.engines) {
      if (engine_name == "one-photographer") {
        // A lone photographer's run is its own baseline.
        if (feed.photographers.size() < 2) continue;
        runs.push_back(RunScenario(scenario.name, OnePhotographerFeed(feed), engine_name));
      } else {
        runs.push_back(RunScenario(scenario.name, feed, engine_name));
      }
      rmse_of[engine_name] = runs.back()["center_rmse_m"].get<double>();
    }
    if (rmse_of.count("sub-models") && rmse_of.count("one-photographer")) {
      std::printf("  %s: centre RMSE at the end %.2f mm, %.2fx the same shots' by one "
                  "photographer (%.2f mm)\n",
                  scenario.name.c_str(), 1000 * rmse_of["sub-models"],
                  rmse_of["sub-models"] / rmse_of["one-photographer"],
                  1000 * rmse_of["one-photographer"]);
    }
  }

  std::printf("\n%-14s %-16s %6s %10s %9s %8s %10s %6s %17s %10s %7s\n", "run", "engine",
              "shots", "at arrival", "partnered", "at end", "longest", "wrong",
              "centre RMSE (mm)", "median", "models");
  for (const nlohmann::json& run : runs) {
    std::printf("%-14s %-16s %6d %10d %4d/%-4d %8d %10d %3d/%-2d %8.2f (%5.2f) %7.0f ms %7d\n",
                run["scenario"].get<std::string>().c_str(),
                run["engine"].get<std::string>().c_str(), run["shots"].get<int>(),
                run["posed_at_arrival"].get<int>(),
                run["with_partner_posed_at_arrival"].get<int>(), run["with_partner"].get<int>(),
                run["posed_at_end"].get<int>(),
                run["longest_unposed_at_arrival"].get<int>(), run["wrong_at_arrival"].get<int>(),
                run["wrong_at_end"].get<int>(), 1000 * run["center_rmse_m"].get<double>(),
                1000 * run["arrival_center_rmse_m"].get<double>(),
                run["all_stages_median_ms"].get<double>(), run["models"].get<int>());
  }
  std::printf("(posed at arrival; of the shots with an initial partner at arrival, those "
              "posed then; posed at the end; longest stretch without a pose at arrival; "
              "wrong at arrival/at the end; centre RMSE at the end (at arrival); all stages "
              "median per shot; sub-models at the end)\n");
  const nlohmann::json json = {{"bench", "agents"},
                               {"camera", camera_text},
                               {"width", camera.width},
                               {"height", camera.height},
                               {"megapixels", flags.megapixels},
                               {"ring_photos", flags.num_photos},
                               {"step_deg", StepDeg(flags)},
                               {"gap_deg", flags.gap_deg},
                               {"walk_photos", flags.walk_photos},
                               {"seed", flags.seed},
                               {"malloc_policy", malloc_policy},
                               {"runs", runs}};
  std::cout << json.dump() << "\n";
  if (flags.work.empty()) fs::remove_all(work);
  return 0;
}

}  // namespace
}  // namespace flysfm

int main(int argc, char** argv) {
  using namespace flysfm;
  Flags flags;
  CLI::App app("Every shot posed at its arrival? A ring with a gap, and several photographers");
  app.add_option("--scenarios", flags.scenarios,
                 "Any of ring, agents, two (rendered), fountain, temple (--data)")
      ->delimiter(',')
      ->check(CLI::IsMember({"ring", "agents", "two", "fountain", "temple"}))
      ->capture_default_str();
  app.add_option("--engines", flags.engines,
                 "Any of sub-models, one-model (sub-models off), one-photographer (sub-models, "
                 "the same shots by one photographer along the path); each scenario runs on "
                 "each")
      ->delimiter(',')
      ->check(CLI::IsMember({"sub-models", "one-model", "one-photographer"}))
      ->capture_default_str();
  app.add_option("--photos", flags.num_photos,
                 "Shots of the ring (their step is every walk's)")
      ->check(CLI::Range(6, 1000))
      ->capture_default_str();
  app.add_option("--walk-photos", flags.walk_photos,
                 "Shots of each walk of agents and two (0: the ring's step)")
      ->check(CLI::Range(0, 1000))
      ->capture_default_str();
  app.add_option("--gap-deg", flags.gap_deg, "The ring's gap between two consecutive shots")
      ->check(CLI::Range(0.0, 180.0))
      ->capture_default_str();
  app.add_option("--megapixels", flags.megapixels, "Photo size (3:2; 6 is 3000x2000)")
      ->check(CLI::Range(0.05, 60.0))
      ->capture_default_str();
  app.add_option("--seed", flags.seed, "Jitter and texture seed")->capture_default_str();
  app.add_option("--supersampling", flags.supersampling, "Render supersampling")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  app.add_option("--work", flags.work, "Keep the rendered JPEGs here and reuse them");
  bench::AddDataOption(&app, &flags.data);
  app.add_flag("--glibc-malloc-defaults", flags.glibc_malloc_defaults,
               "Leave the allocator as glibc sets it (core/malloc_policy.h's baseline)");
  CLI11_PARSE(app, argc, argv);
  return Main(flags);
}
