// Refinement between shots: the accuracy a paced run reaches with
// refinement off and on, COLMAP 3.8's on the same photos in the same run
// (where `colmap` is installed), and the latency of each image from its
// arrival to its result, off and on, split for the images registered on
// arrival into their own stages after SIFT and the time they waited (for a
// refinement unit to end). Ends with one line of JSON.
//
//   bench_refine [--data DIR] [--sets fountain,temple,rendered,fr3,fr1,fr1nok]
//                [--interval S] [--rendered-photos N] [--fr1-intervals S,S]
//                [--fr1-frames N] [--repeat N] [--orders N] [--no-colmap] [--work DIR]
//
// "rendered" is the first --rendered-photos (40) shots of bench_photos'
// session at 6 MP (bench/photo_session.h), rendered into --work/rendered_photos and
// reused from there: the one set whose ground truth has no error of its own.
//
// Images are fed as `flysfm live` feeds them: one every --interval seconds
// (photos: 3.5 s, a photographer's pace; fr3: its 1 Hz; fr1_xyz: its 30 Hz
// and 1 s), the next prepared on the second core, refinement slices while
// none waits (RefineUntilNextFrame), the rest of it and Finish at the end
// (`finish_s`), through the run loop as `flysfm live` runs. COLMAP runs
// exhaustive matching and its mapper with the same intrinsics held fixed,
// on 2 threads, no GPU. Where it ran on photos, a line compares its
// per-image centre errors with refinement on's: a large share in common
// (high correlation, a difference well below either error) says the
// ground truth's own error is what both measure. Another tells it from the
// images: the median reprojection error of each model's observations with
// its own poses and with the true ones (each point triangulated again;
// FitObservationsToPoses). Exact poses fit as well as a model's own; the
// rendered set shows it. One more follows the model as it stood when each
// image arrived (what the live view showed while the next photo was
// taken), off and on: its error's median over the arrivals, and at how many
// on was lower.
//
// --repeat N runs each set off and on N times, off first in the first repeat
// and on first in the second, and so on: the latency figures pool the
// repeats, the accuracy is the first's, and each image's own stages on less
// off (paired by image and repeat) give the difference refinement makes to
// them with a distribution-free 95 % interval: a few milliseconds between
// two runs of a 19-image set are within what the machine itself varies.
//
// --orders N measures the accuracy off and on in N capture orders: as
// captured, then shuffled as `flysfm batch --shuffle K` does, K = 1 .. N - 1.
// An on-the-fly model depends on the order its images came in (which pair
// starts it, which image each track's LSM template is cut from), and on the
// photo sets its centre error varies by a factor of two or more between
// orders: a difference between off and on in one order says little. The
// paired differences (on less off, per order) get the median and the sign
// test's distribution-free 95 % interval. Where the poses are known, each
// order's model (refinement on) is also asked how much worse the true poses
// fit its observations (RMS, as above): about nothing says that order's
// error is the estimate's scatter, not a bias its observations carry.

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include "bench/bench_session.h"
#include "bench/photo_session.h"
#include "geometry/statistics.h"
#include "core/engine.h"
#include "core/malloc_policy.h"
#include "io/evaluation/evaluation.h"
#include "io/formats/colmap_model.h"
#include "io/formats/trajectory.h"
#include "io/run/run_writer.h"
#include "io/sources/image_source.h"
#include "tests/testing/datasets.h"

namespace flysfm {
namespace {

namespace fs = std::filesystem;

struct DataSet {
  std::string name;
  fs::path image_dir;  // what COLMAP reads
  std::vector<Frame> frames;
  std::string camera;  // --camera, in the engine's pixel convention; empty: none
  // Ground truth: poses by image name (photos: camera centres compared
  // after Sim3, observations fitted to the poses), or a trajectory (TUM;
  // ATE after Sim3).
  std::map<std::string, Rigid3d> poses;
  std::vector<StampedPose> trajectory;
  std::vector<double> intervals_s;
  bool colmap = true;  // whether COLMAP is run on it
};

struct Accuracy {
  int registered = 0;
  std::optional<double> error_m;  // centre RMSE or ATE RMSE after Sim3
  // Photos: per image, its camera centre after the Sim3 less the true one.
  std::map<std::string, Eigen::Vector3d> centre_errors;
  std::optional<PoseFit> pose_fit;
};

// The model's centres against the truth: its registered images' poses with
// a true pose (photos), or its trajectory (TUM). Copied when an image
// arrives, before it is added (microseconds for a few hundred images, within
// that image's latency), and compared after the run: the Sim3 alignments
// stay out of every latency.
struct ModelCentres {
  std::vector<Eigen::Vector3d> estimated, reference;  // photos
  std::vector<std::string> names;                      // photos, as `estimated`
  std::vector<StampedPose> trajectory;                 // TUM
};

ModelCentres CentresOf(const Reconstruction& model, const DataSet& set) {
  ModelCentres centres;
  if (set.poses.empty()) {
    centres.trajectory = TrajectoryOf(model);
    return centres;
  }
  for (const image_t id : model.RegisteredImageIds()) {
    const Image& image = model.image(id);
    const auto truth = set.poses.find(image.name);
    if (truth == set.poses.end()) continue;
    centres.estimated.push_back(ProjectionCenter(*image.cam_from_world));
    centres.reference.push_back(ProjectionCenter(truth->second));
    centres.names.push_back(image.name);
  }
  return centres;
}

std::optional<double> ErrorOf(const ModelCentres& centres, const DataSet& set) {
  if (set.poses.empty()) {
    const TrajectoryEvaluation evaluation = EvaluateTrajectory(centres.trajectory, set.trajectory);
    if (!evaluation.ate) return std::nullopt;
    return evaluation.ate->rmse;
  }
  const auto errors = ComparePositionsAfterSim3(centres.estimated, centres.reference);
  if (!errors) return std::nullopt;
  return errors->rmse;
}

Accuracy Evaluate(const Reconstruction& model, const DataSet& set) {
  Accuracy accuracy;
  accuracy.registered = int(model.NumRegisteredImages());
  const ModelCentres centres = CentresOf(model, set);
  if (!set.poses.empty()) {
    if (const auto errors = ComparePositionsAfterSim3(centres.estimated, centres.reference)) {
      accuracy.error_m = errors->rmse;
      for (std::size_t i = 0; i < centres.names.size(); ++i) {
        accuracy.centre_errors[centres.names[i]] =
            errors->reference_from_estimate * centres.estimated[i] - centres.reference[i];
      }
    }
    accuracy.pose_fit = FitObservationsToPoses(model, set.poses);
  } else {
    accuracy.error_m = ErrorOf(centres, set);
  }
  return accuracy;
}

// How much of two reconstructions' centre errors they share: where both err
// alike, against independent pipelines, the error is likely the ground
// truth's own. The correlation of their per-image error vectors (stacked),
// and the RMS over images of the difference of the two vectors.
struct SharedError {
  double correlation = 0;
  double difference_rms_m = 0;
};

std::optional<SharedError> CompareErrors(const Accuracy& a, const Accuracy& b) {
  double ab = 0, aa = 0, bb = 0, difference = 0;
  int count = 0;
  for (const auto& [name, error_a] : a.centre_errors) {
    const auto error_b = b.centre_errors.find(name);
    if (error_b == b.centre_errors.end()) continue;
    ab += error_a.dot(error_b->second);
    aa += error_a.squaredNorm();
    bb += error_b->second.squaredNorm();
    difference += (error_a - error_b->second).squaredNorm();
    ++count;
  }
  if (count < 3 || aa == 0 || bb == 0) return std::nullopt;
  return SharedError{ab / std::sqrt(aa * bb), std::sqrt(difference / count)};
}


struct Run {
  Accuracy accuracy;
  // The error of the model as it stood when each image arrived (what a live
  // view showed the photographer while taking it), one per arrival;
  // nullopt while it could not be compared (fewer than 3 images).
  std::vector<std::optional<double>> live_error_m;
  std::vector<double> latency_ms;  // arrival to result, per registered image
  // Of the images registered on arrival: the time of their own stages after
  // SIFT, and the time they waited (for the image before them, or for a
  // refinement step to end), which is the latency less all their stages.
  std::vector<StageTimes> own_times;
  std::map<std::string, double> own_ms_by_name;
  std::vector<double> delay_ms;
  Engine::RefinementTotals refinement;
  double finish_s = 0;
  double wall_s = 0;
};

double OwnMs(const StageTimes& times) { return times.total - times.decode - times.features; }

std::vector<double> OwnMs(const Run& run) {
  std::vector<double> own_ms;
  for (const StageTimes& times : run.own_times) own_ms.push_back(OwnMs(times));
  return own_ms;
}

// Through the run loop, as `flysfm live` runs: one image every `interval_s`,
// refinement slices while none waits, what is left of it and Finish at the
// end.
Run RunPaced(const DataSet& set, bool refine, double interval_s) {
  Engine::Options options;
  options.refinement.enabled = refine;
  Engine engine(options, set.camera.empty()
                             ? std::nullopt
                             : std::optional<Camera>(Camera::FromString(set.camera, 0, 0)));
  std::vector<ModelCentres> live;
  bench::SessionOptions session_options;
  session_options.run.print = false;
  session_options.interval_s = interval_s;
  session_options.hooks.on_arrival = [&](const Engine& engine, const PreparedFrame&) {
    live.push_back(CentresOf(engine.reconstruction(), set));
  };
  const bench::Session session = bench::RunSession(&engine, set.frames, session_options);
  Run run;
  for (const RunLoop::Reported& reported : session.run.results) {
    const ImageResult& result = reported.result;
    if (result.status != ImageStatus::kRegistered || !reported.delay_ms) continue;
    run.latency_ms.push_back(*reported.delay_ms);
    // Of the images registered on arrival, their own call's result.
    if (!reported.arriving_image) continue;
    run.own_times.push_back(result.times);
    run.own_ms_by_name[result.name] = OwnMs(result.times);
    run.delay_ms.push_back(*reported.delay_ms - result.times.total);
  }
  run.finish_s = session.run.end_s;
  run.wall_s = session.run.wall_s;
  run.accuracy = Evaluate(engine.reconstruction(), set);
  for (const ModelCentres& centres : live) run.live_error_m.push_back(ErrorOf(centres, set));
  run.refinement = engine.refinement_totals();
  return run;
}

// COLMAP's camera: its principal point convention is ours shifted by half a
// pixel (docs/engine.md, "Pixel convention").
std::string ColmapCameraParams(const Camera& camera) {
  std::vector<double> params = camera.params;
  if (camera.model_id == CameraModelId::kPinhole) {
    params[2] += 0.5;
    params[3] += 0.5;
  }
  std::ostringstream text;
  text.precision(10);
  for (std::size_t i = 0; i < params.size(); ++i) text << (i ? "," : "") << params[i];
  return text.str();
}

// Feature extraction, exhaustive matching and the mapper, intrinsics fixed;
// nullopt when a step failed (its log is in `work`).
std::optional<Accuracy> RunColmap(const DataSet& set, const fs::path& work, double* seconds) {
  fs::remove_all(work);
  fs::create_directories(work / "sparse");
  const Camera camera = Camera::FromString(set.camera, 0, 0);
  const std::string db = (work / "database.db").string();
  const std::string log = " >> " + (work / "colmap.log").string() + " 2>&1";
  const std::string steps[] = {
      "colmap feature_extractor --database_path " + db + " --image_path " +
          set.image_dir.string() + " --ImageReader.camera_model PINHOLE" +
          " --ImageReader.single_camera 1 --ImageReader.camera_params " +
          ColmapCameraParams(camera) +
          " --SiftExtraction.use_gpu 0 --SiftExtraction.num_threads 2",
      "colmap exhaustive_matcher --database_path " + db +
          " --SiftMatching.use_gpu 0 --SiftMatching.num_threads 2",
      "colmap mapper --database_path " + db + " --image_path " + set.image_dir.string() +
          " --output_path " + (work / "sparse").string() +
          " --Mapper.num_threads 2 --Mapper.ba_refine_focal_length 0" +
          " --Mapper.ba_refine_principal_point 0 --Mapper.ba_refine_extra_params 0",
  };
  const auto start = std::chrono::steady_clock::now();
  for (const std::string& step : steps) {
    if (std::system(("QT_QPA_PLATFORM=offscreen " + step + log).c_str()) != 0) return std::nullopt;
  }
  *seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  if (!fs::exists(work / "sparse" / "0")) return std::nullopt;
  return Evaluate(ReadColmapModel(work / "sparse" / "0"), set);
}

// One of the shared photo sets, COLMAP reading the folder its images are in.
DataSet Photos(testing::PhotoSet photos, double interval_s) {
  DataSet set;
  set.name = std::move(photos.name);
  set.image_dir = photos.frames.front().path.parent_path();
  set.frames = std::move(photos.frames);
  set.camera = std::move(photos.camera);
  set.poses = std::move(photos.cam_from_world);
  set.intervals_s = {interval_s};
  return set;
}

DataSet Tum(const fs::path& dir, const std::string& name, const std::string& camera,
            std::vector<double> intervals_s, int max_frames, bool colmap) {
  DataSet set;
  set.name = name;
  set.image_dir = dir / "rgb";
  set.frames = ListTumSequence(dir);
  if (max_frames > 0 && int(set.frames.size()) > max_frames) set.frames.resize(max_frames);
  set.camera = camera;
  set.trajectory = ReadTumTrajectory((dir / "groundtruth.txt").string());
  set.intervals_s = std::move(intervals_s);
  set.colmap = colmap;
  return set;
}

// The first `num_photos` shots of bench_photos' rendered session at 6 MP,
// rendered into `dir` (kept there for the next run): ground truth without an
// error of its own, which no real set has.
DataSet Rendered(int num_photos, const fs::path& dir, double interval_s) {
  const int width = 3000;
  const std::uint32_t seed = 1;
  const int supersampling = 1;
  DataSet set;
  set.camera = PhotoSessionCamera(width);
  const Camera camera = Camera::FromString(set.camera, width, width * 2 / 3);
  PrepareRenderFolder(dir, seed, camera, supersampling);
  const std::vector<Shot> shots = MakePhotoSession(num_photos, seed);
  RenderPhotoSession(shots, camera, seed, supersampling, dir, 2);
  set.name = "rendered, " + std::to_string(num_photos) + " photos";
  set.image_dir = dir;
  for (const Shot& shot : shots) {
    Frame frame;
    frame.name = shot.name;
    frame.path = dir / shot.name;
    frame.timestamp = double(set.frames.size());
    set.frames.push_back(frame);
    set.poses[shot.name] = shot.cam_from_world;
  }
  // COLMAP reads the whole folder: photos of a longer run before go.
  for (const auto& entry : fs::directory_iterator(dir)) {
    if (entry.path().extension() == ".jpg" && !set.poses.count(entry.path().filename())) {
      fs::remove(entry.path());
    }
  }
  set.intervals_s = {interval_s};
  return set;
}

// Adds a repeat's latencies to `run`'s.
void Pool(const Run& repeat, Run* run) {
  const auto append = [](const auto& from, auto* to) {
    to->insert(to->end(), from.begin(), from.end());
  };
  append(repeat.latency_ms, &run->latency_ms);
  append(repeat.own_times, &run->own_times);
  append(repeat.delay_ms, &run->delay_ms);
}

// The median of `values` with the distribution-free 95 % interval of the
// sign test: the order statistics k + 1 and n - k (from 1) for the largest k
// with P(Binomial(n, 1/2) <= k) <= 2.5 %, which the median lies outside only
// when at most k values fall on one side of it; {median, min, max} for n < 6.
std::array<double, 3> MedianWithInterval(std::vector<double> values) {
  std::sort(values.begin(), values.end());
  const int n = int(values.size());
  if (n == 0) return {0, 0, 0};
  int k = 0;  // values left out on each side
  double at_most = 0;  // P(Binomial(n, 1/2) <= i)
  for (int i = 0; i < n; ++i) {
    at_most += std::exp(std::lgamma(n + 1.0) - std::lgamma(i + 1.0) -
                        std::lgamma(n - i + 1.0) - n * std::log(2.0));
    if (at_most > 0.025) break;
    k = i;
  }
  return {Median(values), values[k], values[n - 1 - k]};
}

// The median of each of the images' own stages (after SIFT), by name.
std::vector<std::pair<const char*, double>> OwnStageMedians(const Run& run) {
  std::vector<std::pair<const char*, double>> medians;
  for (const auto& [name, stage] : StageTimes::Stages()) {
    if (stage == &StageTimes::decode || stage == &StageTimes::features) continue;
    std::vector<double> values;
    for (const StageTimes& times : run.own_times) values.push_back(times.*stage);
    medians.emplace_back(name, Median(values));
  }
  return medians;
}

nlohmann::json ToJson(const Run& run, const char* unit, double scale) {
  nlohmann::json own_stages;
  for (const auto& [name, median] : OwnStageMedians(run)) own_stages[name] = median;
  return {{"registered", run.accuracy.registered},
          {std::string("error_") + unit,
           run.accuracy.error_m ? nlohmann::json(*run.accuracy.error_m * scale) : nullptr},
          {"latency_ms",
           {{"median", Median(run.latency_ms)},
            {"p95", Quantile(run.latency_ms, 0.95)},
            {"max", Quantile(run.latency_ms, 1.0)}}},
          {"own_ms",
           {{"median", Quantile(OwnMs(run), 0.5)}, {"p95", Quantile(OwnMs(run), 0.95)}}},
          {"own_stage_median_ms", own_stages},
          {"delay_ms",
           {{"median", Quantile(run.delay_ms, 0.5)}, {"p95", Quantile(run.delay_ms, 0.95)}}},
          {"refinement", ToJson(run.refinement)},
          {"finish_s", run.finish_s},
          {"wall_s", run.wall_s}};
}

struct Flags {
  std::string data;
  std::vector<std::string> sets = {"fountain", "temple", "rendered", "fr3", "fr1"};
  int rendered_photos = 40;
  double interval_s = 3.5;
  std::vector<double> fr1_intervals_s = {1.0 / 30, 1.0};
  int fr1_frames = 330;
  int repeat = 1;
  int orders = 1;
  bool no_colmap = false;
  std::string work = (fs::temp_directory_path() / "bench_refine").string();
};

// The set `key` names; std::invalid_argument for an unknown key, and what
// reading the data throws.
DataSet MakeSet(const std::string& key, const Flags& flags) {
  const fs::path data = flags.data;
  if (key == "fountain") return Photos(testing::FountainP11(data), flags.interval_s);
  if (key == "temple") return Photos(testing::TempleRing19(data), flags.interval_s);
  if (key == "rendered") {
    return Rendered(flags.rendered_photos, fs::path(flags.work) / "rendered_photos",
                    flags.interval_s);
  }
  if (key == "fr3") {
    return Tum(data / "tum/rgbd_dataset_freiburg3_long_office_household_superglue17",
               "fr3 17 frames", "PINHOLE 535.4,539.2,320.1,247.6", {1.0}, 0, true);
  }
  const fs::path fr1 = data / "tum/rgbd_dataset_freiburg1_xyz";
  // COLMAP 3.8 fails on this calibration (docs/peers.md); ORB-SLAM's 0.90 cm
  // is the figure to beat.
  if (key == "fr1") {
    return Tum(fr1, "fr1_xyz",
               "FULL_OPENCV 517.3,516.5,318.6,255.3,0.2624,-0.9531,-0.0054,0.0026,1.1633,0,0,0",
               flags.fr1_intervals_s, flags.fr1_frames, false);
  }
  // The same frames self-calibrating: a narrow baseline never settles the
  // focal length, so the schedule's global BAs run to the end.
  if (key == "fr1nok") {
    return Tum(fr1, "fr1_xyz without K", "", flags.fr1_intervals_s, flags.fr1_frames, false);
  }
  throw std::invalid_argument("unknown set " + key);
}

// Refinement off against on on one set at one interval.
struct Comparison {
  Run off, on;
  // Each image's own stages on less off, paired by image and repeat, and
  // each repeat's median of them.
  std::vector<double> own_on_less_off;
  std::vector<double> repeat_medians;
  std::array<double, 3> own_difference{};
  // The error off and on in each capture order (missing where a run
  // registered too little to be compared), the first as captured; whether
  // an order's larger error is a bias the observations carry (true poses
  // fit them worse: RMS with the true poses over the model's own, less 1)
  // or the estimate's own scatter.
  std::vector<std::optional<double>> off_errors, on_errors, on_fit_excess;
  std::array<double, 3> by_order{};
  // The model as each image arrived, off and on (as captured), paired by
  // arrival. One run's arrivals are not independent samples (each model
  // grows from the one before), so no interval: how often on was lower.
  std::vector<double> live_off, live_on;
  int live_on_lower = 0;
};

void RunRepeats(const DataSet& set, double interval, int repeat, Comparison* c) {
  for (int r = 0; r < repeat; ++r) {
    // Every second repeat runs on first, so that whatever the order of two
    // runs in one process does to their times falls on both alike.
    Run off_repeat, on_repeat;
    if (r % 2 == 0) {
      off_repeat = RunPaced(set, false, interval);
      on_repeat = RunPaced(set, true, interval);
    } else {
      on_repeat = RunPaced(set, true, interval);
      off_repeat = RunPaced(set, false, interval);
    }
    std::vector<double> differences;
    for (const auto& [name, ms] : on_repeat.own_ms_by_name) {
      const auto it = off_repeat.own_ms_by_name.find(name);
      if (it != off_repeat.own_ms_by_name.end()) differences.push_back(ms - it->second);
    }
    c->repeat_medians.push_back(Median(differences));
    c->own_on_less_off.insert(c->own_on_less_off.end(), differences.begin(), differences.end());
    if (r == 0) {
      c->off = off_repeat;
      c->on = on_repeat;
    } else {
      Pool(off_repeat, &c->off);
      Pool(on_repeat, &c->on);
    }
  }
  c->own_difference = MedianWithInterval(c->own_on_less_off);
}

void RunOrders(const DataSet& set, double interval, int orders, double scale, Comparison* c) {
  c->off_errors = {c->off.accuracy.error_m};
  c->on_errors = {c->on.accuracy.error_m};
  std::vector<std::optional<PoseFit>> on_fits = {c->on.accuracy.pose_fit};
  for (int order = 1; order < orders; ++order) {
    DataSet shuffled = set;
    ShuffleFrames(&shuffled.frames, std::uint32_t(order));
    c->off_errors.push_back(RunPaced(shuffled, false, interval).accuracy.error_m);
    const Accuracy on_accuracy = RunPaced(shuffled, true, interval).accuracy;
    c->on_errors.push_back(on_accuracy.error_m);
    on_fits.push_back(on_accuracy.pose_fit);
  }
  for (const std::optional<PoseFit>& fit : on_fits) {
    c->on_fit_excess.push_back(
        fit && fit->model_rms_px > 0
            ? std::optional<double>(fit->truth_rms_px / fit->model_rms_px - 1)
            : std::nullopt);
  }
  std::vector<double> on_less_off;
  for (int order = 0; order < orders; ++order) {
    if (c->off_errors[order] && c->on_errors[order]) {
      on_less_off.push_back((*c->on_errors[order] - *c->off_errors[order]) * scale);
    }
  }
  c->by_order = MedianWithInterval(on_less_off);
}

void CompareLive(double scale, Comparison* c) {
  const std::size_t n = std::min(c->off.live_error_m.size(), c->on.live_error_m.size());
  for (std::size_t i = 0; i < n; ++i) {
    const std::optional<double>& error_off = c->off.live_error_m[i];
    const std::optional<double>& error_on = c->on.live_error_m[i];
    if (!error_off || !error_on) continue;
    c->live_off.push_back(*error_off * scale);
    c->live_on.push_back(*error_on * scale);
    c->live_on_lower += *error_on < *error_off;
  }
}

// "1.23 mm", or "-" without an error.
std::string ErrorText(const std::optional<double>& error_m, double scale, const char* unit) {
  char text[32] = "-";
  if (error_m) std::snprintf(text, sizeof(text), "%.2f %s", *error_m * scale, unit);
  return text;
}

std::string LatencyText(const Run& run) {
  char text[96];
  std::snprintf(text, sizeof(text), "%.0f / %.0f / %.0f (own %.0f, waited %.0f / %.0f)",
                Median(run.latency_ms), Quantile(run.latency_ms, 0.95),
                Quantile(run.latency_ms, 1.0), Median(OwnMs(run)), Median(run.delay_ms),
                Quantile(run.delay_ms, 0.95));
  return text;
}

std::string FitText(const std::optional<PoseFit>& fit) {
  char text[80] = "-";
  if (fit) {
    std::snprintf(text, sizeof(text), "%.3f / %.3f px", fit->model_median_px,
                  fit->truth_median_px);
  }
  return text;
}

void PrintOrders(const DataSet& set, const Comparison& c, int orders, double scale,
                 const char* unit) {
  std::printf("|   error in %d capture orders (as captured, then shuffled): off", orders);
  const auto print_errors = [&](const std::vector<std::optional<double>>& errors) {
    std::vector<double> known;
    for (const auto& error_m : errors) {
      std::printf(" %s", ErrorText(error_m, scale, unit).c_str());
      if (error_m) known.push_back(*error_m * scale);
    }
    if (!known.empty()) std::printf(" (mean %.2f %s)", Mean(known), unit);
  };
  print_errors(c.off_errors);
  std::printf("; on");
  print_errors(c.on_errors);
  std::printf("; on less off, paired by order: median %+.2f %s, 95 %% interval [%+.2f, %+.2f] "
              "|\n",
              c.by_order[0], unit, c.by_order[1], c.by_order[2]);
  if (set.poses.empty()) return;
  std::printf("|   observations' RMS reprojection error with the true poses over the model's "
              "own, refinement on, in each order:");
  for (const auto& excess : c.on_fit_excess) {
    if (excess) {
      std::printf(" %+.1f %%", *excess * 100);
    } else {
      std::printf(" -");
    }
  }
  std::printf(" |\n");
}

void PrintComparison(const DataSet& set, double interval, const Comparison& c,
                     const std::optional<Accuracy>& colmap, double colmap_s, bool colmap_run,
                     int repeat, int orders, double scale, const char* unit) {
  std::string colmap_text = colmap_run ? "failed" : "not run";
  if (colmap) {
    colmap_text = ErrorText(colmap->error_m, scale, unit) + " (" +
                  std::to_string(colmap->registered) + " reg., " +
                  std::to_string(int(colmap_s)) + " s)";
  }
  const Engine::RefinementTotals& refinement = c.on.refinement;
  std::printf("| %s | %.3g s | %d / %d of %zu | %s | %s | %s | %s | %s | %d, %d / %d (%d "
              "linked), %d, %.1f |\n",
              set.name.c_str(), interval, c.off.accuracy.registered, c.on.accuracy.registered,
              set.frames.size(), ErrorText(c.off.accuracy.error_m, scale, unit).c_str(),
              ErrorText(c.on.accuracy.error_m, scale, unit).c_str(), colmap_text.c_str(),
              LatencyText(c.off).c_str(), LatencyText(c.on).c_str(), refinement.num_slices,
              refinement.num_pairs_verified, refinement.num_pairs_tried,
              refinement.num_pairs_linked, refinement.num_global_bas, refinement.ms / 1000);
  std::printf("|   own stages' medians, ms off / on: ");
  const auto off_stages = OwnStageMedians(c.off);
  const auto on_stages = OwnStageMedians(c.on);
  for (std::size_t i = 0; i < off_stages.size(); ++i) {
    std::printf("%s%s %.1f / %.1f", i ? ", " : "", off_stages[i].first, off_stages[i].second,
                on_stages[i].second);
  }
  std::printf(" |\n|   own stages on less off, paired by image (%zu pairs, %d repeat%s): median "
              "%+.1f ms, 95 %% interval [%+.1f, %+.1f]; each repeat's median:",
              c.own_on_less_off.size(), repeat, repeat > 1 ? "s" : "", c.own_difference[0],
              c.own_difference[1], c.own_difference[2]);
  for (const double median : c.repeat_medians) std::printf(" %+.1f", median);
  std::printf(" |\n");
  if (orders > 1) PrintOrders(set, c, orders, scale, unit);
  std::printf("|   the model as each image arrived, error median over the %zu arrivals with 3 "
              "images or more in both: off %.2f %s, on %.2f %s; on lower at %d |\n",
              c.live_off.size(), Median(c.live_off), unit, Median(c.live_on), unit,
              c.live_on_lower);
  if (colmap) {
    if (const std::optional<SharedError> shared = CompareErrors(c.on.accuracy, *colmap)) {
      std::printf("|   centre errors, refinement on and COLMAP, per image: correlation %.2f, "
                  "RMS of their difference %.2f %s |\n",
                  shared->correlation, shared->difference_rms_m * scale, unit);
    }
  }
  if (c.on.accuracy.pose_fit) {
    std::printf("|   observations' reprojection error, median, with the model's own poses / "
                "with the true poses: refinement on %s, COLMAP %s |\n",
                FitText(c.on.accuracy.pose_fit).c_str(),
                FitText(colmap ? colmap->pose_fit : std::nullopt).c_str());
  }
  std::fflush(stdout);
}

nlohmann::json OptionalJson(const std::optional<double>& value, double scale = 1) {
  return value ? nlohmann::json(*value * scale) : nlohmann::json(nullptr);
}

nlohmann::json FitJson(const std::optional<PoseFit>& fit) {
  if (!fit) return nullptr;
  return {{"own_median_px", fit->model_median_px}, {"true_median_px", fit->truth_median_px}};
}

nlohmann::json ComparisonJson(const DataSet& set, double interval, const Comparison& c,
                              const std::optional<Accuracy>& colmap, double colmap_s, int repeat,
                              int orders, double scale, const std::string& unit) {
  nlohmann::json entry = {{"set", set.name},
                          {"images", set.frames.size()},
                          {"interval_s", interval},
                          {"off", ToJson(c.off, unit.c_str(), scale)},
                          {"on", ToJson(c.on, unit.c_str(), scale)},
                          {"repeats", repeat},
                          {"own_on_less_off_ms",
                           {{"median", c.own_difference[0]},
                            {"interval95", {c.own_difference[1], c.own_difference[2]}},
                            {"pairs", c.own_on_less_off.size()},
                            {"repeat_medians", c.repeat_medians}}}};
  if (c.on.accuracy.pose_fit) entry["on"]["pose_fit"] = FitJson(c.on.accuracy.pose_fit);
  entry["live"] = {{"arrivals", c.live_off.size()},
                   {"off_median_" + unit, Median(c.live_off)},
                   {"on_median_" + unit, Median(c.live_on)},
                   {"on_lower", c.live_on_lower}};
  if (orders > 1) {
    const auto errors_json = [&](const std::vector<std::optional<double>>& errors) {
      nlohmann::json values = nlohmann::json::array();
      for (const auto& error_m : errors) values.push_back(OptionalJson(error_m, scale));
      return values;
    };
    entry["orders"] = {{"off_" + unit, errors_json(c.off_errors)},
                       {"on_" + unit, errors_json(c.on_errors)},
                       {"on_less_off",
                        {{"median", c.by_order[0]}, {"interval95", {c.by_order[1], c.by_order[2]}}}}};
    if (!set.poses.empty()) {
      nlohmann::json excess = nlohmann::json::array();
      for (const auto& value : c.on_fit_excess) excess.push_back(OptionalJson(value));
      entry["orders"]["on_true_over_own_rms_less_1"] = excess;
    }
  }
  if (colmap) {
    entry["colmap"] = {{"registered", colmap->registered},
                       {"error_" + unit, OptionalJson(colmap->error_m, scale)},
                       {"seconds", colmap_s},
                       {"pose_fit", FitJson(colmap->pose_fit)}};
    if (const std::optional<SharedError> shared = CompareErrors(c.on.accuracy, *colmap)) {
      entry["colmap"]["error_correlation_with_on"] = shared->correlation;
      entry["colmap"]["error_difference_from_on_" + unit] = shared->difference_rms_m * scale;
    }
  }
  return entry;
}

int Main(const Flags& flags) {
  const bool colmap = !flags.no_colmap && std::system("command -v colmap > /dev/null 2>&1") == 0;
  nlohmann::json json = {{"bench", "refine"}, {"sets", nlohmann::json::array()}};
  std::printf("| set | interval | registered off / on | error off | error on | COLMAP 3.8 | "
              "latency ms off: median / p95 / max (own stages after SIFT: median; waited: "
              "median / p95) | on | refinement: slices, pairs verified / tried (linked, not "
              "tried), global BAs, s |\n|---|---|---|---|---|---|---|---|---|\n");
  for (const std::string& key : flags.sets) {
    DataSet set;
    try {
      set = MakeSet(key, flags);
    } catch (const std::exception& e) {
      std::cerr << "bench_refine: " << e.what() << " (set FLYSFM_DATA or --data)\n";
      return 2;
    }
    const bool photos = !set.poses.empty();
    const char* unit = photos ? "mm" : "cm";
    const double scale = photos ? 1000 : 100;
    std::optional<Accuracy> colmap_accuracy;
    double colmap_s = 0;
    if (colmap && set.colmap) {
      colmap_accuracy = RunColmap(set, fs::path(flags.work) / key, &colmap_s);
    }
    for (const double interval : set.intervals_s) {
      Comparison comparison;
      RunRepeats(set, interval, flags.repeat, &comparison);
      RunOrders(set, interval, flags.orders, scale, &comparison);
      CompareLive(scale, &comparison);
      PrintComparison(set, interval, comparison, colmap_accuracy, colmap_s, colmap && set.colmap,
                      flags.repeat, flags.orders, scale, unit);
      json["sets"].push_back(ComparisonJson(set, interval, comparison, colmap_accuracy, colmap_s,
                                            flags.repeat, flags.orders, scale, unit));
    }
  }
  std::cout << json.dump() << "\n";
  return 0;
}

}  // namespace
}  // namespace flysfm

int main(int argc, char** argv) {
  using namespace flysfm;
  ApplyMallocPolicy();  // as flysfm does: the engine measured as it runs there
  Flags flags;
  CLI::App app("Refinement between shots, off against on, and COLMAP on the same photos");
  bench::AddDataOption(&app, &flags.data);
  app.add_option("--sets", flags.sets, "Sets: fountain, temple, rendered, fr3, fr1, fr1nok")
      ->delimiter(',')
      ->capture_default_str();
  app.add_option("--interval", flags.interval_s, "Seconds between photos")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  app.add_option("--rendered-photos", flags.rendered_photos, "Photos of the rendered set")
      ->check(CLI::Range(2, 100000))
      ->capture_default_str();
  app.add_option("--fr1-intervals", flags.fr1_intervals_s, "Seconds between fr1_xyz frames")
      ->delimiter(',')
      ->capture_default_str();
  app.add_option("--fr1-frames", flags.fr1_frames, "fr1_xyz frames (0: all)")
      ->capture_default_str();
  app.add_option("--repeat", flags.repeat, "Runs of each set, off and on")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  app.add_option("--orders", flags.orders, "Capture orders (as captured, then shuffled)")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  app.add_flag("--no-colmap", flags.no_colmap, "Do not run COLMAP");
  app.add_option("--work", flags.work, "Folder for COLMAP's runs and the rendered photos")
      ->capture_default_str();
  CLI11_PARSE(app, argc, argv);
  return Main(flags);
}
