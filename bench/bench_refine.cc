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
// (`finish_s`), as RunEngine does. COLMAP runs
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

#include <nlohmann/json.hpp>

#include "bench/photo_session.h"
#include "core/engine.h"
#include "core/malloc_policy.h"
#include "io/evaluation/evaluation.h"
#include "io/formats/colmap_model.h"
#include "io/formats/trajectory.h"
#include "io/run/run_writer.h"
#include "io/sources/image_source.h"
#include "io/sources/prepared_source.h"
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

double Percentile(std::vector<double> values, double p) {
  if (values.empty()) return 0;
  std::sort(values.begin(), values.end());
  return values[std::size_t(p * double(values.size() - 1) + 0.5)];
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

Run RunPaced(const DataSet& set, bool refine, double interval_s) {
  const auto start = std::chrono::steady_clock::now();
  Engine::Options options;
  options.refinement.enabled = refine;
  Engine engine(options, set.camera.empty()
                             ? std::nullopt
                             : std::optional<Camera>(Camera::FromString(set.camera, 0, 0)));
  FrameListSource source(set.frames, interval_s);
  PreparedFrameSource prepared(&source, engine.options());
  std::map<std::string, std::chrono::steady_clock::time_point> arrivals;
  Run run;
  const auto note = [&](const std::vector<ImageResult>& results, bool on_arrival) {
    const auto now = std::chrono::steady_clock::now();
    for (const ImageResult& result : results) {
      if (result.status != ImageStatus::kRegistered) continue;
      const double latency =
          std::chrono::duration<double, std::milli>(now - arrivals.at(result.name)).count();
      run.latency_ms.push_back(latency);
      if (!on_arrival || result.name != results.front().name) continue;
      const StageTimes& times = result.times;
      run.own_times.push_back(times);
      run.own_ms_by_name[result.name] = OwnMs(times);
      run.delay_ms.push_back(latency - times.total);
    }
  };
  std::vector<ModelCentres> live;
  while (true) {
    RefineUntilNextFrame(&engine, prepared, 1.0,
                         [&](Engine::RefinementSlice* slice) { note(slice->registered, false); });
    std::optional<PreparedFrame> frame = prepared.Next();
    if (!frame) break;
    live.push_back(CentresOf(engine.reconstruction(), set));
    arrivals[frame->frame.name] = frame->frame.arrival;
    note(engine.AddImage(std::move(*frame)), true);
  }
  const auto finish_start = std::chrono::steady_clock::now();
  note(engine.RefineToEnd(), false);
  engine.Finish();
  const auto end = std::chrono::steady_clock::now();
  run.finish_s = std::chrono::duration<double>(end - finish_start).count();
  run.wall_s = std::chrono::duration<double>(end - start).count();
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

std::vector<std::string> Split(const std::string& text) {
  std::vector<std::string> parts;
  std::stringstream stream(text);
  for (std::string part; std::getline(stream, part, ',');) parts.push_back(part);
  return parts;
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
  return {Percentile(values, 0.5), values[k], values[n - 1 - k]};
}

// The median of each of the images' own stages (after SIFT), by name.
std::vector<std::pair<const char*, double>> OwnStageMedians(const Run& run) {
  std::vector<std::pair<const char*, double>> medians;
  for (const auto& [name, stage] : StageTimes::Stages()) {
    if (stage == &StageTimes::decode || stage == &StageTimes::features) continue;
    std::vector<double> values;
    for (const StageTimes& times : run.own_times) values.push_back(times.*stage);
    medians.emplace_back(name, Percentile(values, 0.5));
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
           {{"median", Percentile(run.latency_ms, 0.5)},
            {"p95", Percentile(run.latency_ms, 0.95)},
            {"max", Percentile(run.latency_ms, 1.0)}}},
          {"own_ms",
           {{"median", Percentile(OwnMs(run), 0.5)}, {"p95", Percentile(OwnMs(run), 0.95)}}},
          {"own_stage_median_ms", own_stages},
          {"delay_ms",
           {{"median", Percentile(run.delay_ms, 0.5)}, {"p95", Percentile(run.delay_ms, 0.95)}}},
          {"refinement", ToJson(run.refinement)},
          {"finish_s", run.finish_s},
          {"wall_s", run.wall_s}};
}

}  // namespace
}  // namespace flysfm

int main(int argc, char** argv) {
  using namespace flysfm;
  ApplyMallocPolicy();  // as flysfm does: the engine measured as it runs there
  std::string data = std::getenv("FLYSFM_DATA") ? std::getenv("FLYSFM_DATA")
                                                : FLYSFM_DEFAULT_DATA_DIR;
  std::vector<std::string> sets = {"fountain", "temple", "rendered", "fr3", "fr1"};
  int rendered_photos = 40;
  double interval_s = 3.5;
  std::vector<double> fr1_intervals_s = {1.0 / 30, 1.0};
  int fr1_frames = 330;
  int repeat = 1;
  int orders = 1;
  bool colmap = std::system("command -v colmap > /dev/null 2>&1") == 0;
  fs::path work = fs::temp_directory_path() / "bench_refine";
  for (int i = 1; i < argc; ++i) {
    const bool has_value = i + 1 < argc;
    if (!std::strcmp(argv[i], "--data") && has_value) {
      data = argv[++i];
    } else if (!std::strcmp(argv[i], "--sets") && has_value) {
      sets = Split(argv[++i]);
    } else if (!std::strcmp(argv[i], "--interval") && has_value) {
      interval_s = std::atof(argv[++i]);
    } else if (!std::strcmp(argv[i], "--fr1-intervals") && has_value) {
      fr1_intervals_s.clear();
      for (const std::string& value : Split(argv[++i])) fr1_intervals_s.push_back(std::stod(value));
    } else if (!std::strcmp(argv[i], "--rendered-photos") && has_value &&
               std::atoi(argv[i + 1]) >= 2) {
      rendered_photos = std::atoi(argv[++i]);
    } else if (!std::strcmp(argv[i], "--fr1-frames") && has_value) {
      fr1_frames = std::atoi(argv[++i]);
    } else if (!std::strcmp(argv[i], "--repeat") && has_value && std::atoi(argv[i + 1]) > 0) {
      repeat = std::atoi(argv[++i]);
    } else if (!std::strcmp(argv[i], "--orders") && has_value && std::atoi(argv[i + 1]) > 0) {
      orders = std::atoi(argv[++i]);
    } else if (!std::strcmp(argv[i], "--no-colmap")) {
      colmap = false;
    } else if (!std::strcmp(argv[i], "--work") && has_value) {
      work = argv[++i];
    } else {
      std::cerr << "usage: bench_refine [--data DIR] "
                   "[--sets fountain,temple,rendered,fr3,fr1,fr1nok] [--interval S] "
                   "[--rendered-photos N] [--fr1-intervals S,S] [--fr1-frames N] [--repeat N] "
                   "[--orders N] [--no-colmap] "
                   "[--work DIR]\n";
      return 2;
    }
  }

  nlohmann::json json = {{"bench", "refine"}, {"sets", nlohmann::json::array()}};
  std::printf("| set | interval | registered off / on | error off | error on | COLMAP 3.8 | "
              "latency ms off: median / p95 / max (own stages after SIFT: median; waited: "
              "median / p95) | on | refinement: slices, pairs verified / tried (linked, not "
              "tried), global BAs, s |\n|---|---|---|---|---|---|---|---|---|\n");
  for (const std::string& key : sets) {
    DataSet set;
    try {
      if (key == "fountain") {
        set = Photos(testing::FountainP11(data), interval_s);
      } else if (key == "temple") {
        set = Photos(testing::TempleRing19(data), interval_s);
      } else if (key == "rendered") {
        set = Rendered(rendered_photos, work / "rendered_photos", interval_s);
      } else if (key == "fr3") {
        set = Tum(fs::path(data) / "tum/rgbd_dataset_freiburg3_long_office_household_superglue17",
                  "fr3 17 frames", "PINHOLE 535.4,539.2,320.1,247.6", {1.0}, 0, true);
      } else if (key == "fr1") {
        // COLMAP 3.8 fails on this calibration (ANCHORS.md); ORB-SLAM's 0.90 cm
        // is the figure to beat.
        set = Tum(fs::path(data) / "tum/rgbd_dataset_freiburg1_xyz", "fr1_xyz",
                  "FULL_OPENCV 517.3,516.5,318.6,255.3,0.2624,-0.9531,-0.0054,0.0026,1.1633,"
                  "0,0,0",
                  fr1_intervals_s, fr1_frames, false);
      } else if (key == "fr1nok") {
        // The same frames self-calibrating: a narrow baseline never settles
        // the focal length, so the schedule's global BAs run to the end.
        set = Tum(fs::path(data) / "tum/rgbd_dataset_freiburg1_xyz", "fr1_xyz without K", "",
                  fr1_intervals_s, fr1_frames, false);
      } else {
        std::cerr << "bench_refine: unknown set " << key << "\n";
        return 2;
      }
    } catch (const std::exception& e) {
      std::cerr << "bench_refine: " << e.what() << " (set FLYSFM_DATA or --data)\n";
      return 2;
    }
    const bool photos = !set.poses.empty();
    const char* unit = photos ? "mm" : "cm";
    const double scale = photos ? 1000 : 100;
    std::optional<Accuracy> colmap_accuracy;
    double colmap_s = 0;
    if (colmap && set.colmap) colmap_accuracy = RunColmap(set, work / key, &colmap_s);
    for (const double interval : set.intervals_s) {
      Run off, on;
      std::vector<double> own_on_less_off;
      std::vector<double> repeat_medians;  // of each repeat's differences
      for (int r = 0; r < repeat; ++r) {
        // Every second repeat runs on first, so that whatever the order of
        // two runs in one process does to their times falls on both alike.
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
        repeat_medians.push_back(Percentile(differences, 0.5));
        own_on_less_off.insert(own_on_less_off.end(), differences.begin(), differences.end());
        if (r == 0) {
          off = off_repeat;
          on = on_repeat;
        } else {
          Pool(off_repeat, &off);
          Pool(on_repeat, &on);
        }
      }
      const std::array<double, 3> own_difference = MedianWithInterval(own_on_less_off);
      // The error off and on in each capture order (missing where a run
      // registered too little to be compared), the first as captured.
      std::vector<std::optional<double>> off_errors = {off.accuracy.error_m};
      std::vector<std::optional<double>> on_errors = {on.accuracy.error_m};
      // Whether an order's larger error is a bias the observations carry
      // (true poses fit them worse) or the estimate's own scatter (they fit
      // as well as the model's poses).
      std::vector<std::optional<PoseFit>> on_fits = {on.accuracy.pose_fit};
      for (int order = 1; order < orders; ++order) {
        DataSet shuffled = set;
        ShuffleFrames(&shuffled.frames, std::uint32_t(order));
        off_errors.push_back(RunPaced(shuffled, false, interval).accuracy.error_m);
        const Accuracy on_accuracy = RunPaced(shuffled, true, interval).accuracy;
        on_errors.push_back(on_accuracy.error_m);
        on_fits.push_back(on_accuracy.pose_fit);
      }
      // RMS reprojection error with the true poses over the model's own, less 1.
      std::vector<std::optional<double>> on_fit_excess;
      for (const std::optional<PoseFit>& fit : on_fits) {
        on_fit_excess.push_back(fit && fit->model_rms_px > 0
                                    ? std::optional<double>(fit->truth_rms_px / fit->model_rms_px - 1)
                                    : std::nullopt);
      }
      std::vector<double> on_less_off_by_order;
      for (int order = 0; order < orders; ++order) {
        if (off_errors[order] && on_errors[order]) {
          on_less_off_by_order.push_back((*on_errors[order] - *off_errors[order]) * scale);
        }
      }
      const std::array<double, 3> by_order = MedianWithInterval(on_less_off_by_order);
      // The model as each image arrived, off and on (as captured), paired by
      // arrival. One run's arrivals are not independent samples (each model
      // grows from the one before), so no interval: how often on was lower.
      std::vector<double> live_off, live_on;
      int live_on_lower = 0;
      for (std::size_t i = 0; i < std::min(off.live_error_m.size(), on.live_error_m.size()); ++i) {
        const std::optional<double>& error_off = off.live_error_m[i];
        const std::optional<double>& error_on = on.live_error_m[i];
        if (!error_off || !error_on) continue;
        live_off.push_back(*error_off * scale);
        live_on.push_back(*error_on * scale);
        live_on_lower += *error_on < *error_off;
      }
      const auto error = [&](const std::optional<double>& error_m) {
        char text[32] = "-";
        if (error_m) std::snprintf(text, sizeof(text), "%.2f %s", *error_m * scale, unit);
        return std::string(text);
      };
      const auto latency = [](const Run& run) {
        char text[96];
        std::snprintf(text, sizeof(text), "%.0f / %.0f / %.0f (own %.0f, waited %.0f / %.0f)",
                      Percentile(run.latency_ms, 0.5), Percentile(run.latency_ms, 0.95),
                      Percentile(run.latency_ms, 1.0), Percentile(OwnMs(run), 0.5),
                      Percentile(run.delay_ms, 0.5), Percentile(run.delay_ms, 0.95));
        return std::string(text);
      };
      std::string colmap_text = colmap && set.colmap ? "failed" : "not run";
      if (colmap_accuracy) {
        colmap_text = error(colmap_accuracy->error_m) + " (" +
                      std::to_string(colmap_accuracy->registered) + " reg., " +
                      std::to_string(int(colmap_s)) + " s)";
      }
      std::printf("| %s | %.3g s | %d / %d of %zu | %s | %s | %s | %s | %s | %d, %d / %d "
                  "(%d linked), %d, %.1f |\n",
                  set.name.c_str(), interval, off.accuracy.registered, on.accuracy.registered,
                  set.frames.size(), error(off.accuracy.error_m).c_str(),
                  error(on.accuracy.error_m).c_str(), colmap_text.c_str(), latency(off).c_str(),
                  latency(on).c_str(), on.refinement.num_slices,
                  on.refinement.num_pairs_verified, on.refinement.num_pairs_tried,
                  on.refinement.num_pairs_linked, on.refinement.num_global_bas,
                  on.refinement.ms / 1000);
      std::printf("|   own stages' medians, ms off / on: ");
      const auto off_stages = OwnStageMedians(off);
      const auto on_stages = OwnStageMedians(on);
      for (std::size_t i = 0; i < off_stages.size(); ++i) {
        std::printf("%s%s %.1f / %.1f", i ? ", " : "", off_stages[i].first, off_stages[i].second,
                    on_stages[i].second);
      }
      std::printf(" |\n|   own stages on less off, paired by image (%zu pairs, %d repeat%s): "
                  "median %+.1f ms, 95 %% interval [%+.1f, %+.1f]; each repeat's median:",
                  own_on_less_off.size(), repeat, repeat > 1 ? "s" : "", own_difference[0],
                  own_difference[1], own_difference[2]);
      for (const double median : repeat_medians) std::printf(" %+.1f", median);
      std::printf(" |\n");
      if (orders > 1) {
        std::printf("|   error in %d capture orders (as captured, then shuffled): off", orders);
        const auto print_errors = [&](const std::vector<std::optional<double>>& errors) {
          double sum = 0;
          int count = 0;
          for (const auto& error_m : errors) {
            std::printf(" %s", error(error_m).c_str());
            if (error_m) sum += *error_m, ++count;
          }
          if (count > 0) std::printf(" (mean %.2f %s)", sum / count * scale, unit);
        };
        print_errors(off_errors);
        std::printf("; on");
        print_errors(on_errors);
        std::printf("; on less off, paired by order: median %+.2f %s, 95 %% interval [%+.2f, "
                    "%+.2f] |\n",
                    by_order[0], unit, by_order[1], by_order[2]);
        if (!set.poses.empty()) {
          std::printf("|   observations' RMS reprojection error with the true poses over the "
                      "model's own, refinement on, in each order:");
          for (const auto& excess : on_fit_excess) {
            if (excess) {
              std::printf(" %+.1f %%", *excess * 100);
            } else {
              std::printf(" -");
            }
          }
          std::printf(" |\n");
        }
      }
      std::printf("|   the model as each image arrived, error median over the %zu arrivals with 3 "
                  "images or more in both: off %.2f %s, on %.2f %s; on lower at %d |\n",
                  live_off.size(), Percentile(live_off, 0.5), unit, Percentile(live_on, 0.5),
                  unit, live_on_lower);
      std::optional<SharedError> shared;
      if (colmap_accuracy) shared = CompareErrors(on.accuracy, *colmap_accuracy);
      if (shared) {
        std::printf("|   centre errors, refinement on and COLMAP, per image: correlation "
                    "%.2f, RMS of their difference %.2f %s |\n",
                    shared->correlation, shared->difference_rms_m * scale, unit);
      }
      const auto fit_text = [](const std::optional<PoseFit>& fit) {
        char text[80] = "-";
        if (fit) {
          std::snprintf(text, sizeof(text), "%.3f / %.3f px", fit->model_median_px,
                        fit->truth_median_px);
        }
        return std::string(text);
      };
      if (on.accuracy.pose_fit) {
        std::printf("|   observations' reprojection error, median, with the model's own poses / "
                    "with the true poses: refinement on %s, COLMAP %s |\n",
                    fit_text(on.accuracy.pose_fit).c_str(),
                    fit_text(colmap_accuracy ? colmap_accuracy->pose_fit : std::nullopt).c_str());
      }
      std::fflush(stdout);
      nlohmann::json entry = {{"set", set.name},
                              {"images", set.frames.size()},
                              {"interval_s", interval},
                              {"off", ToJson(off, unit, scale)},
                              {"on", ToJson(on, unit, scale)},
                              {"repeats", repeat},
                              {"own_on_less_off_ms",
                               {{"median", own_difference[0]},
                                {"interval95", {own_difference[1], own_difference[2]}},
                                {"pairs", own_on_less_off.size()},
                                {"repeat_medians", repeat_medians}}}};
      const auto fit_json = [](const std::optional<PoseFit>& fit) {
        if (!fit) return nlohmann::json(nullptr);
        return nlohmann::json{{"own_median_px", fit->model_median_px},
                              {"true_median_px", fit->truth_median_px}};
      };
      if (on.accuracy.pose_fit) entry["on"]["pose_fit"] = fit_json(on.accuracy.pose_fit);
      entry["live"] = {{"arrivals", live_off.size()},
                       {std::string("off_median_") + unit, Percentile(live_off, 0.5)},
                       {std::string("on_median_") + unit, Percentile(live_on, 0.5)},
                       {"on_lower", live_on_lower}};
      if (orders > 1) {
        const auto errors_json = [&](const std::vector<std::optional<double>>& errors) {
          nlohmann::json values = nlohmann::json::array();
          for (const auto& error_m : errors) {
            values.push_back(error_m ? nlohmann::json(*error_m * scale) : nullptr);
          }
          return values;
        };
        entry["orders"] = {{std::string("off_") + unit, errors_json(off_errors)},
                           {std::string("on_") + unit, errors_json(on_errors)},
                           {"on_less_off",
                            {{"median", by_order[0]}, {"interval95", {by_order[1], by_order[2]}}}}};
        if (!set.poses.empty()) {
          nlohmann::json excess_json = nlohmann::json::array();
          for (const auto& excess : on_fit_excess) {
            excess_json.push_back(excess ? nlohmann::json(*excess) : nullptr);
          }
          entry["orders"]["on_true_over_own_rms_less_1"] = excess_json;
        }
      }
      if (colmap_accuracy) {
        entry["colmap"] = {{"registered", colmap_accuracy->registered},
                           {std::string("error_") + unit,
                            colmap_accuracy->error_m
                                ? nlohmann::json(*colmap_accuracy->error_m * scale)
                                : nullptr},
                           {"seconds", colmap_s},
                           {"pose_fit", fit_json(colmap_accuracy->pose_fit)}};
        if (shared) {
          entry["colmap"]["error_correlation_with_on"] = shared->correlation;
          entry["colmap"][std::string("error_difference_from_on_") + unit] =
              shared->difference_rms_m * scale;
        }
      }
      json["sets"].push_back(entry);
    }
  }
  std::cout << json.dump() << "\n";
  return 0;
}
