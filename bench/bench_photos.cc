// The engine on a long photo session rather than a video: a DSLR walking
// around a building (synthetic, exact ground truth), 6 MP by default
// (--megapixels 24 for 6000x4000), 300 shots 1-3 m apart on several loops at
// different heights and distances, the later loops revisiting the first one.
// Shows whether the per-image time stays flat and memory stays bounded as the
// session grows, and the accuracy reached (camera centres after Sim3; the
// self-calibrated focal length when the camera is unknown). Ends with one
// line of JSON.
//
//   bench_photos [--photos N] [--megapixels 6|24] [--calibrated] [--seed S]
//                [--supersampling K] [--work DIR] [--window-budget MB] [--profile]
//                [--data DIR] [--no-real] [--glibc-malloc-defaults]
//
// After the synthetic session, the same per-photo figures on the real 6 MP
// sets of --data (default $FLYSFM_DATA or the configured folder):
// fountain-P11 and sceaux_castle, each with its K given and without
// (--no-real skips them).
//
// Each view is rendered by io/synthetic's renderer, written as a JPEG
// (quality 92, no EXIF, so the uncalibrated engine must guess the focal
// length) and fed as a file, as `flysfm batch` feeds a folder: the next photo
// is decoded and its features extracted on the second core while the engine
// works (io/sources/prepared_source.h). Rendering is timed apart; it is not
// the engine's. With --work the JPEGs are kept there and reused by a later
// run with the same seed and size (rendering 300 photos takes minutes).
// --window-budget sets LsmImageStore::Options::window_budget_megabytes.
// --glibc-malloc-defaults leaves the allocator as glibc sets it, the baseline
// of core/malloc_policy.h (compare the page faults and the stage times).
//
// --profile adds an offline look at why two-view verification costs more on
// photos than on 640x480 frames: sample pairs of the session are matched and
// verified again with each RANSAC timed, then the same matches are verified
// in the pixel scale of the 1600 px feature image and of a 640 px frame; and
// one LSM pyramid is built at full resolution and at 640x480.

#include <sys/resource.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iostream>
#include <map>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>
#include <opencv2/imgproc.hpp>

#include "bench/photo_session.h"
#include "core/engine.h"
#include "core/malloc_policy.h"
#include "geometry/two_view_geometry.h"
#include "io/evaluation/evaluation.h"
#include "io/sources/image_source.h"
#include "io/sources/prepared_source.h"
#include "lsm/lsm.h"
#include "matching/matcher.h"
#include "tests/testing/datasets.h"

namespace flysfm {
namespace {

using Clock = std::chrono::steady_clock;

double MsSince(Clock::time_point start) {
  return std::chrono::duration<double, std::milli>(Clock::now() - start).count();
}

double Percentile(std::vector<double> values, double fraction) {
  if (values.empty()) return 0;
  std::sort(values.begin(), values.end());
  const double at = fraction * (values.size() - 1);
  const std::size_t below = std::size_t(std::floor(at));
  const std::size_t above = std::min(below + 1, values.size() - 1);
  return values[below] + (at - below) * (values[above] - values[below]);
}
double Median(const std::vector<double>& values) { return Percentile(values, 0.5); }

// Whole process, in MB, from /proc/self/status ("VmRSS", "VmHWM").
double ProcStatusMb(const std::string& field) {
  std::ifstream status("/proc/self/status");
  for (std::string line; std::getline(status, line);) {
    if (line.compare(0, field.size() + 1, field + ":") == 0) {
      return std::atof(line.c_str() + field.size() + 1) / 1024.0;
    }
  }
  return -1;
}

// Resets VmHWM to the current RSS (Linux >= 4.0), so that the peak reported
// is the engine's and not the rendering's.
bool ResetPeakRss() {
  std::ofstream clear("/proc/self/clear_refs");
  clear << "5";
  return bool(clear.flush());
}

// ---------------------------------------------------------------- profile

// Times of one pair's verification (ms) and what it found.
struct PairProfile {
  int raw_matches = 0;
  double match_ms = 0;
  double f_ms = 0, h_ms = 0, e_ms = 0;
  int f_iterations = 0, h_iterations = 0, e_iterations = 0;
  // EstimateCalibratedTwoViewGeometry on the same matches, in the pixels of
  // the photo, of the 1600 px feature image and of a 640 px wide frame.
  double full_ms = 0, feature_scale_ms = 0, video_scale_ms = 0;
  int full_inliers = 0, feature_scale_inliers = 0, video_scale_inliers = 0;
};

Camera Scaled(const Camera& camera, double scale) {
  Camera scaled = camera;
  for (double& p : scaled.params) p *= scale;
  scaled.width = int(std::round(camera.width * scale));
  scaled.height = int(std::round(camera.height * scale));
  return scaled;
}

nlohmann::json Profile(const std::vector<Frame>& frames, const Camera& camera,
                       const Engine::Options& options) {
  const int n = int(frames.size());
  std::map<int, PreparedFrame> prepared;
  const auto get = [&](int i) -> const PreparedFrame& {
    auto it = prepared.find(i);
    if (it == prepared.end()) it = prepared.emplace(i, Engine::Prepare(frames[i], options)).first;
    return it->second;
  };
  // Near pairs (1-4 shots apart) overlap; pairs 10 and 25 shots apart
  // mostly do not, like the low-ranked retrieval candidates the engine still
  // verifies when fewer than max_verified_pairs of them verify.
  std::vector<std::pair<int, int>> pairs;
  for (int k = 1; k <= 4; ++k) {
    const int i = k * n / 5;
    for (const int back : {1, 2, 4, 10, 25}) {
      if (i - back >= 0 && i < n) pairs.emplace_back(i, i - back);
    }
  }
  const TwoViewGeometryOptions& two_view = options.verification.two_view;
  RansacOptions ransac = two_view.ransac;
  ransac.max_error = two_view.max_error_px;
  std::vector<PairProfile> profiles;
  std::printf("\nprofile: sample pairs verified again offline (ms; RANSAC iterations)\n"
              "  pair        raw   match   F (it)      H (it)      E (it)      two-view at "
              "photo / 1600 px / 640 px scale (inliers)\n");
  for (const auto& [i, j] : pairs) {
    const FeatureSet& a = get(i).features;
    const FeatureSet& b = get(j).features;
    PairProfile p;
    auto start = Clock::now();
    const std::vector<FeatureMatch> raw =
        MatchDescriptors(a.descriptors, b.descriptors, options.verification.matching);
    p.match_ms = MsSince(start);
    p.raw_matches = int(raw.size());
    std::vector<Eigen::Vector2d> pa, pb, na, nb;
    for (const FeatureMatch& m : raw) {
      pa.emplace_back(a.keypoints[m.idx1].x, a.keypoints[m.idx1].y);
      pb.emplace_back(b.keypoints[m.idx2].x, b.keypoints[m.idx2].y);
      na.push_back(camera.CamFromImg(pa.back()));
      nb.push_back(camera.CamFromImg(pb.back()));
    }
    if (int(raw.size()) >= two_view.min_num_inliers_f) {
      start = Clock::now();
      const auto f = EstimateFundamentalMatrix(pa, pb, ransac);
      p.f_ms = MsSince(start);
      p.f_iterations = f.num_iterations;
      start = Clock::now();
      const auto h = EstimateHomographyMatrix(pa, pb, ransac);
      p.h_ms = MsSince(start);
      p.h_iterations = h.num_iterations;
      RansacOptions ransac_e = ransac;
      ransac_e.max_error = two_view.max_error_px / camera.MeanFocalLength();
      start = Clock::now();
      const auto e = EstimateEssentialMatrix(na, nb, ransac_e);
      p.e_ms = MsSince(start);
      p.e_iterations = e.num_iterations;
      const auto at_scale = [&](double scale, double* ms, int* inliers) {
        std::vector<Eigen::Vector2d> sa = pa, sb = pb;
        for (auto& x : sa) x *= scale;
        for (auto& x : sb) x *= scale;
        const Camera c = Scaled(camera, scale);
        const auto begin = Clock::now();
        const TwoViewGeometry g = EstimateCalibratedTwoViewGeometry(c, sa, c, sb, two_view);
        *ms = MsSince(begin);
        *inliers = g.num_inliers;
      };
      at_scale(1.0, &p.full_ms, &p.full_inliers);
      const double feature_scale =
          std::min(1.0, double(options.sift.max_image_size) / std::max(camera.width, camera.height));
      at_scale(feature_scale, &p.feature_scale_ms, &p.feature_scale_inliers);
      at_scale(640.0 / camera.width, &p.video_scale_ms, &p.video_scale_inliers);
    }
    std::printf("  %4d-%-4d %6d %7.1f %6.1f (%5d) %5.1f (%5d) %5.1f (%5d)   %6.1f (%d) / "
                "%6.1f (%d) / %6.1f (%d)\n",
                i, j, p.raw_matches, p.match_ms, p.f_ms, p.f_iterations, p.h_ms, p.h_iterations,
                p.e_ms, p.e_iterations, p.full_ms, p.full_inliers, p.feature_scale_ms,
                p.feature_scale_inliers, p.video_scale_ms, p.video_scale_inliers);
    profiles.push_back(p);
  }
  const auto median_of = [&](auto field, int verified) {
    // verified: 1 pairs with enough inliers, 0 without, -1 all.
    std::vector<double> values;
    for (const PairProfile& p : profiles) {
      const bool ok = p.full_inliers >= two_view.min_num_inliers_f;
      if (verified < 0 || ok == bool(verified)) values.push_back(double(p.*field));
    }
    return Median(values);
  };
  nlohmann::json json = {{"pairs", profiles.size()}};
  for (const auto& [label, verified] :
       std::vector<std::pair<std::string, int>>{{"verified", 1}, {"failed", 0}}) {
    int count = 0;
    for (const PairProfile& p : profiles) {
      count += (p.full_inliers >= two_view.min_num_inliers_f) == bool(verified);
    }
    json[label] = {
        {"pairs", count},
        {"median_raw_matches", median_of(&PairProfile::raw_matches, verified)},
        {"median_match_ms", median_of(&PairProfile::match_ms, verified)},
        {"median_f_ms", median_of(&PairProfile::f_ms, verified)},
        {"median_h_ms", median_of(&PairProfile::h_ms, verified)},
        {"median_e_ms", median_of(&PairProfile::e_ms, verified)},
        {"median_f_iterations", median_of(&PairProfile::f_iterations, verified)},
        {"median_h_iterations", median_of(&PairProfile::h_iterations, verified)},
        {"median_e_iterations", median_of(&PairProfile::e_iterations, verified)},
        {"median_two_view_ms_photo_px", median_of(&PairProfile::full_ms, verified)},
        {"median_two_view_ms_feature_px", median_of(&PairProfile::feature_scale_ms, verified)},
        {"median_two_view_ms_640px", median_of(&PairProfile::video_scale_ms, verified)},
        {"median_inliers_photo_px", median_of(&PairProfile::full_inliers, verified)},
        {"median_inliers_feature_px", median_of(&PairProfile::feature_scale_inliers, verified)},
        {"median_inliers_640px", median_of(&PairProfile::video_scale_inliers, verified)}};
    const nlohmann::json& j = json[label];
    std::printf("  median of the %d %s pairs: %.0f raw matches; match %.1f ms; F %.1f ms (%.0f "
                "it), H %.1f ms (%.0f it), E %.1f ms (%.0f it); two-view %.1f ms in photo "
                "pixels, %.1f ms in 1600 px, %.1f ms in 640 px (inliers %.0f / %.0f / %.0f)\n",
                count, label.c_str(), j["median_raw_matches"].get<double>(),
                j["median_match_ms"].get<double>(), j["median_f_ms"].get<double>(),
                j["median_f_iterations"].get<double>(), j["median_h_ms"].get<double>(),
                j["median_h_iterations"].get<double>(), j["median_e_ms"].get<double>(),
                j["median_e_iterations"].get<double>(),
                j["median_two_view_ms_photo_px"].get<double>(),
                j["median_two_view_ms_feature_px"].get<double>(),
                j["median_two_view_ms_640px"].get<double>(),
                j["median_inliers_photo_px"].get<double>(),
                j["median_inliers_feature_px"].get<double>(),
                j["median_inliers_640px"].get<double>());
  }
  // Decoding and SIFT of the sampled photos, run here with the engine idle:
  // against the run's figures, what sharing the two cores costs.
  std::vector<double> decode_ms, features_ms;
  for (const auto& [index, frame] : prepared) {
    decode_ms.push_back(frame.decode_ms);
    features_ms.push_back(frame.features_ms);
  }
  json["alone_decode_ms"] = Median(decode_ms);
  json["alone_features_ms"] = Median(features_ms);
  std::printf("  decode %.0f ms, features %.0f ms (medians of the %zu sampled photos prepared "
              "alone, engine idle)\n",
              Median(decode_ms), Median(features_ms), decode_ms.size());

  // LSM reads whole-resolution pyramids: their cost and size at this
  // resolution against a 640x480 frame's.
  const cv::Mat& grey = get(pairs.empty() ? 0 : pairs.front().first).grey;
  cv::Mat small;
  cv::resize(grey, small, cv::Size(640, 480), 0, 0, cv::INTER_AREA);
  const int levels = options.lsm_images.num_pyramid_levels;
  const auto pyramid = [&](const cv::Mat& image, double* ms, double* mb) {
    const auto begin = Clock::now();
    const std::vector<LsmImage> built = BuildLsmPyramid(image, levels);
    *ms = MsSince(begin);
    std::size_t bytes = 0;
    for (const LsmImage& level : built) bytes += level.ByteSize();
    *mb = bytes / 1048576.0;
  };
  double photo_ms, photo_mb, frame_ms, frame_mb;
  pyramid(grey, &photo_ms, &photo_mb);
  pyramid(small, &frame_ms, &frame_mb);
  std::printf("  LSM search pyramid (%d levels, built once for each new photo): %.0f ms and "
              "%.1f MB at %dx%d, %.1f ms and %.2f MB at 640x480; a whole 8-bit grey photo is "
              "%.1f MB (older photos keep only windows, within %d MB)\n",
              levels, photo_ms, photo_mb, grey.cols, grey.rows, frame_ms, frame_mb,
              grey.total() / 1048576.0, options.lsm_images.window_budget_megabytes);
  json["lsm_pyramid_ms_photo"] = photo_ms;
  json["lsm_pyramid_mb_photo"] = photo_mb;
  json["lsm_pyramid_ms_640x480"] = frame_ms;
  json["lsm_pyramid_mb_640x480"] = frame_mb;
  json["grey_mb_per_photo"] = grey.total() / 1048576.0;
  return json;
}

// ---------------------------------------------------------------- the run

StageTimes SumOfTimes(const std::vector<ImageResult>& results) {
  StageTimes sum;
  for (const ImageResult& result : results) {
    for (const auto& [name, stage] : StageTimes::Stages()) sum.*stage += result.times.*stage;
  }
  sum.UpdateTotal();
  return sum;
}

// One engine run as `flysfm batch` makes it: the next photo prepared on the
// second core. `on_photo` sees each call's results, all its stages' times
// and the engine's own time.
struct SessionRun {
  std::vector<double> call_ms, engine_ms;
  std::vector<StageTimes> call_times;
  std::vector<int> verified_pairs, candidates;
  Reconstruction model;
  std::size_t pending = 0;
  double finish_s = 0;
  double wall_s = 0;
  // The last focal length the initial pairs' F put in place of the guess.
  std::optional<double> focal_length_from_pairs;
  double peak_mb = 0;     // VmHWM after Finish (reset before, where Linux lets us)
  double maxrss_mb = 0;   // the whole process's
  bool peak_reset = false;
  // Minor page faults of the whole process from the engine's start to the
  // end of Finish: memory handed back to the system and faulted in again
  // (core/malloc_policy.h).
  long page_faults = 0;
};

using PhotoCallback = std::function<void(const Engine&, const std::vector<ImageResult>&,
                                         const StageTimes&, double engine_ms)>;

SessionRun RunSession(const std::vector<Frame>& frames, const Engine::Options& options,
                      const std::optional<Camera>& known_camera, const PhotoCallback& on_photo) {
  SessionRun run;
  run.peak_reset = ResetPeakRss();
  rusage usage;
  getrusage(RUSAGE_SELF, &usage);
  run.page_faults = -usage.ru_minflt;
  const auto start = Clock::now();
  Engine engine(options, known_camera);
  FrameListSource source(frames);
  PreparedFrameSource prepared(&source, options);
  while (std::optional<PreparedFrame> frame = prepared.Next()) {
    const auto call = Clock::now();
    const std::vector<ImageResult> out = engine.AddImage(std::move(*frame));
    run.engine_ms.push_back(MsSince(call));
    const StageTimes times = SumOfTimes(out);
    run.call_times.push_back(times);
    run.call_ms.push_back(times.total);
    run.verified_pairs.push_back(out.front().num_verified_pairs);
    run.candidates.push_back(out.front().num_candidates);
    for (const ImageResult& result : out) {
      if (result.focal_length_from_pairs) {
        run.focal_length_from_pairs = result.focal_length_from_pairs;
      }
    }
    if (on_photo) on_photo(engine, out, times, run.engine_ms.back());
  }
  const auto finish = Clock::now();
  engine.Finish();
  run.finish_s = MsSince(finish) / 1000;
  run.wall_s = MsSince(start) / 1000;
  run.peak_mb = ProcStatusMb("VmHWM");
  getrusage(RUSAGE_SELF, &usage);
  run.page_faults += usage.ru_minflt;
  run.maxrss_mb = usage.ru_maxrss / 1024.0;
  run.pending = engine.PendingImageNames().size();
  run.model = engine.reconstruction();
  return run;
}

// ", the initial pairs' F gave N px" when they replaced the guess.
std::string FromPairsText(const SessionRun& run) {
  if (!run.focal_length_from_pairs) return "";
  char text[64];
  std::snprintf(text, sizeof(text), ", the initial pairs' F gave %.1f px",
                *run.focal_length_from_pairs);
  return text;
}

nlohmann::json Stats(const std::vector<double>& v) {
  return nlohmann::json{{"median", Median(v)},
                        {"p95", Percentile(v, 0.95)},
                        {"max", v.empty() ? 0 : *std::max_element(v.begin(), v.end())}};
}

// Each stage's median over calls [begin, end).
nlohmann::json StageMedians(const std::vector<StageTimes>& call_times, std::size_t begin,
                            std::size_t end) {
  nlohmann::json stages;
  for (const auto& [name, stage] : StageTimes::Stages()) {
    std::vector<double> v;
    for (std::size_t i = begin; i < end; ++i) v.push_back(call_times[i].*stage);
    stages[name] = Median(v);
  }
  return stages;
}

// A real photo set of ../shared/data, with or without its K: the same
// per-photo figures (too few photos for a growth), the centres against
// ground truth where there is one, the focal length against K.
nlohmann::json RunRealSet(const testing::PhotoSet& set, bool k_given) {
  const std::string name = set.name + (k_given ? ", K given" : ", without K");
  std::optional<Camera> known_camera;
  if (k_given) known_camera = Camera::FromString(set.camera, 0, 0);
  const SessionRun run = RunSession(set.frames, Engine::Options(), known_camera, nullptr);
  double final_focal = 0;
  for (const auto& [camera_id, c] : run.model.cameras()) final_focal = c.MeanFocalLength();
  const std::optional<PositionErrors> errors =
      set.cam_from_world.empty() ? std::nullopt : CompareCentersByName(run.model, set.Centres());
  const nlohmann::json stages = StageMedians(run.call_times, 0, run.call_times.size());
  const nlohmann::json all = Stats(run.call_ms);
  const nlohmann::json engine = Stats(run.engine_ms);
  std::printf("%-30s registered %zu/%zu; all stages median %.0f ms, p95 %.0f ms; engine median "
              "%.0f ms; peak RSS %.0f MB; ",
              name.c_str(), run.model.NumRegisteredImages(), set.frames.size(),
              all["median"].get<double>(), all["p95"].get<double>(),
              engine["median"].get<double>(), run.peak_mb);
  if (errors) std::printf("centres RMSE %.2f mm; ", errors->rmse * 1000);
  std::printf("focal %.1f px (K %.1f, %+.2f %%%s)\n", final_focal, set.focal_length,
              100 * (final_focal / set.focal_length - 1), FromPairsText(run).c_str());
  std::printf("  stage medians (ms):");
  for (const auto& [stage_name, stage] : StageTimes::Stages()) {
    std::printf(" %s %.0f", stage_name, stages[stage_name].get<double>());
  }
  std::printf("\n");
  std::fflush(stdout);
  return nlohmann::json{{"name", name},
                        {"calibrated", k_given},
                        {"photos", set.frames.size()},
                        {"registered", run.model.NumRegisteredImages()},
                        {"all_stages_ms", all},
                        {"engine_ms", engine},
                        {"stage_median_ms", stages},
                        {"peak_rss_mb", run.peak_mb},
                        {"center_rmse_m", errors ? errors->rmse : -1.0},
                        {"final_focal_px", final_focal},
                        {"focal_length_from_pairs_px", run.focal_length_from_pairs.value_or(0)},
                        {"true_focal_px", set.focal_length}};
}

// fountain-P11 (Strecha's cameras) and sceaux_castle (its K.txt, no poses),
// each with its K given and without (sceaux keeps its EXIF focal length).
nlohmann::json RunRealSets(const std::filesystem::path& data) {
  std::printf("\nreal photo sets in %s, fed as `flysfm batch` does:\n", data.c_str());
  nlohmann::json sets = nlohmann::json::array();
  for (const testing::PhotoSet& set : {testing::FountainP11(data), testing::SceauxCastle(data)}) {
    for (const bool k_given : {true, false}) sets.push_back(RunRealSet(set, k_given));
  }
  return sets;
}

}  // namespace
}  // namespace flysfm

int main(int argc, char** argv) {
  using namespace flysfm;
  int num_photos = 300;
  int megapixels = 6;
  bool calibrated = false;
  bool profile = false;
  int seed = 1;
  int supersampling = 1;
  std::string work;
  int window_budget_mb = LsmImageStore::Options().window_budget_megabytes;
  std::string data =
      std::getenv("FLYSFM_DATA") ? std::getenv("FLYSFM_DATA") : FLYSFM_DEFAULT_DATA_DIR;
  bool real_sets = true;
  bool glibc_malloc_defaults = false;
  for (int i = 1; i < argc; ++i) {
    const bool has_value = i + 1 < argc;
    if (!std::strcmp(argv[i], "--photos") && has_value) {
      num_photos = std::atoi(argv[++i]);
    } else if (!std::strcmp(argv[i], "--megapixels") && has_value) {
      megapixels = std::atoi(argv[++i]);
    } else if (!std::strcmp(argv[i], "--seed") && has_value) {
      seed = std::atoi(argv[++i]);
    } else if (!std::strcmp(argv[i], "--supersampling") && has_value) {
      supersampling = std::atoi(argv[++i]);
    } else if (!std::strcmp(argv[i], "--work") && has_value) {
      work = argv[++i];
    } else if (!std::strcmp(argv[i], "--window-budget") && has_value) {
      window_budget_mb = std::atoi(argv[++i]);
    } else if (!std::strcmp(argv[i], "--calibrated")) {
      calibrated = true;
    } else if (!std::strcmp(argv[i], "--profile")) {
      profile = true;
    } else if (!std::strcmp(argv[i], "--data") && has_value) {
      data = argv[++i];
    } else if (!std::strcmp(argv[i], "--no-real")) {
      real_sets = false;
    } else if (!std::strcmp(argv[i], "--glibc-malloc-defaults")) {
      glibc_malloc_defaults = true;
    } else {
      num_photos = -1;
      break;
    }
  }
  if (num_photos < 10 || (megapixels != 6 && megapixels != 24) || supersampling < 1 ||
      window_budget_mb < 0) {
    std::cerr << "usage: bench_photos [--photos N>=10] [--megapixels 6|24] [--calibrated] "
                 "[--seed S] [--supersampling K] [--work DIR] [--window-budget MB] "
                 "[--profile] [--data DIR] [--no-real] [--glibc-malloc-defaults]\n";
    return 2;
  }
  // As flysfm, before any thread starts: the engine as it runs there.
  const bool malloc_policy = !glibc_malloc_defaults && ApplyMallocPolicy();

  // 3:2 sensor; a 30 mm-equivalent lens (36 mm film width): f = 30/36 width.
  const int width = megapixels == 24 ? 6000 : 3000;
  const int height = width * 2 / 3;
  const std::string camera_text = PhotoSessionCamera(width);
  const Camera camera = Camera::FromString(camera_text, width, height);
  const double focal = camera.params[0];

  // The folder of JPEGs: --work (kept, reused when its manifest matches) or
  // a temporary one (removed at the end).
  namespace fs = std::filesystem;
  const bool keep = !work.empty();
  const fs::path dir = keep ? fs::path(work)
                            : fs::temp_directory_path() /
                                  ("bench_photos_" + std::to_string(::getpid()));
  PrepareRenderFolder(dir, std::uint32_t(seed), camera, supersampling);

  const std::vector<Shot> shots = MakePhotoSession(num_photos, std::uint32_t(seed));
  std::printf("bench_photos: %d photos of %dx%d (%d MP), focal %.0f px (30 mm equivalent), %s; "
              "seed %d; photos in %s\n",
              num_photos, width, height, megapixels, focal,
              calibrated ? "CALIBRATED (the true K given, held fixed)"
                         : "UNCALIBRATED (focal guessed by the engine, self-calibrated in BA)",
              seed, dir.c_str());
  std::fflush(stdout);

  // Rendering: on both cores (the engine does not run yet); not engine time.
  const std::vector<double> render_ms =
      RenderPhotoSession(shots, camera, std::uint32_t(seed), supersampling, dir, 2);
  if (render_ms.empty()) {
    std::printf("render: all %d photos reused from %s\n", num_photos, dir.c_str());
  } else {
    std::printf("render: %zu photos at supersampling %d, median %.0f ms per photo (one core; "
                "two rendered at a time)\n",
                render_ms.size(), supersampling, Median(render_ms));
  }
  std::uintmax_t jpeg_bytes = 0;
  std::vector<Frame> frames;
  std::map<std::string, Eigen::Vector3d> true_centers;
  double mean_distance = 0;
  for (int i = 0; i < num_photos; ++i) {
    Frame frame;
    frame.name = shots[i].name;
    frame.path = dir / shots[i].name;
    frame.timestamp = i;
    jpeg_bytes += fs::file_size(frame.path);
    frames.push_back(frame);
    true_centers[shots[i].name] = ProjectionCenter(shots[i].cam_from_world);
    mean_distance += shots[i].distance_to_building / num_photos;
  }
  std::printf("photos: mean JPEG %.1f MB; mean distance to the building %.1f m\n",
              jpeg_bytes / 1048576.0 / num_photos, mean_distance);

  // The engine, as `flysfm batch` makes it (with --camera when calibrated).
  Engine::Options options;
  options.lsm_images.window_budget_megabytes = window_budget_mb;
  std::optional<Camera> known_camera;
  if (calibrated) known_camera = Camera::FromString(camera_text, 0, 0);
  const double rss_before_mb = ProcStatusMb("VmRSS");
  std::vector<std::pair<int, double>> rss_samples;
  int index = 0;
  const SessionRun run = RunSession(
      frames, options, known_camera,
      [&](const Engine& engine, const std::vector<ImageResult>& out, const StageTimes& times,
          double engine_ms) {
        ++index;
        std::printf("[%4d] %-16s %-10s all stages %6.0f ms (decode %4.0f, features %4.0f, "
                    "verification %5.0f, lsm %5.0f, ba %5.0f), engine %6.0f ms, %2d/%2d pairs, "
                    "model %d img / %d pts%s%s\n",
                    index, out.front().name.c_str(), ImageStatusName(out.front().status),
                    times.total, times.decode, times.features, times.verification, times.lsm,
                    times.ba, engine_ms, out.front().num_verified_pairs,
                    out.front().num_candidates, out.back().model_images,
                    out.back().model_points, out.front().reason.empty() ? "" : "  ",
                    out.front().reason.c_str());
        if (index % 50 == 0 || index == num_photos) {
          rss_samples.emplace_back(index, ProcStatusMb("VmRSS"));
          std::printf("       RSS after %d photos: %.0f MB (LSM store: windows %.0f MB, whole "
                      "images %.0f MB)\n",
                      index, rss_samples.back().second,
                      engine.lsm_images().window_bytes() / 1048576.0,
                      engine.lsm_images().whole_bytes() / 1048576.0);
        }
        std::fflush(stdout);
      });
  // Accuracy.
  const std::optional<PositionErrors> errors = CompareCentersByName(run.model, true_centers);
  double final_focal = 0;
  for (const auto& [camera_id, c] : run.model.cameras()) final_focal = c.MeanFocalLength();
  const double focal_error = final_focal / focal - 1;

  // Figures.
  const auto window = [&](std::size_t begin, std::size_t end) {
    end = std::min(end, run.call_times.size());
    begin = std::min(begin, end);
    std::vector<double> total(run.call_ms.begin() + begin, run.call_ms.begin() + end);
    std::vector<double> engine(run.engine_ms.begin() + begin, run.engine_ms.begin() + end);
    std::vector<double> pairs(run.verified_pairs.begin() + begin, run.verified_pairs.begin() + end);
    return nlohmann::json{{"photos", {begin, end}},
                          {"median_all_stages_ms", Median(total)},
                          {"median_engine_ms", Median(engine)},
                          {"median_verified_pairs", Median(pairs)},
                          {"stage_median_ms", StageMedians(run.call_times, begin, end)}};
  };
  const std::size_t n = run.call_ms.size();
  const nlohmann::json early = window(50, 100);
  const nlohmann::json late = window(n >= 50 ? n - 50 : 0, n);
  const double growth = early["median_all_stages_ms"].get<double>() > 0
                            ? late["median_all_stages_ms"].get<double>() /
                                  early["median_all_stages_ms"].get<double>()
                            : 0;
  const double engine_growth = early["median_engine_ms"].get<double>() > 0
                                   ? late["median_engine_ms"].get<double>() /
                                         early["median_engine_ms"].get<double>()
                                   : 0;
  nlohmann::json rss = nlohmann::json::object();
  for (const auto& [index, mb] : rss_samples) rss[std::to_string(index)] = mb;

  const nlohmann::json all_stats = Stats(run.call_ms);
  const nlohmann::json engine_stats = Stats(run.engine_ms);
  std::printf("\n%s, %d photos of %dx%d: registered %zu, %zu pending, %zu points; "
              "%.1f s in all (%.2f s per photo), Finish (pending + global BA) %.1f s\n",
              calibrated ? "calibrated" : "uncalibrated", num_photos, width, height,
              run.model.NumRegisteredImages(), run.pending,
              run.model.NumPoints3D(), run.wall_s, run.wall_s / num_photos, run.finish_s);
  std::printf("per-photo time, all stages (decode + features + engine): median %.0f ms, p95 "
              "%.0f ms, max %.0f ms\n",
              all_stats["median"].get<double>(), all_stats["p95"].get<double>(),
              all_stats["max"].get<double>());
  std::printf("per-photo engine time (AddImage; decode + features ran ahead on the 2nd "
              "core): median %.0f ms, p95 %.0f ms, max %.0f ms\n",
              engine_stats["median"].get<double>(), engine_stats["p95"].get<double>(),
              engine_stats["max"].get<double>());
  std::printf("growth, median of the last 50 / photos 50-100: all stages %.2f, engine %.2f\n",
              growth, engine_growth);
  std::printf("  %-14s %12s %12s\n", "stage (ms)", "photos 50-100", "last 50");
  for (const auto& [name, stage] : StageTimes::Stages()) {
    std::printf("  %-14s %12.1f %12.1f\n", name, early["stage_median_ms"][name].get<double>(),
                late["stage_median_ms"][name].get<double>());
  }
  std::printf("  %-14s %12.1f %12.1f\n", "verified pairs",
              early["median_verified_pairs"].get<double>(),
              late["median_verified_pairs"].get<double>());
  // The engine verifies candidates in retrieval order until
  // max_verified_pairs verify: an image with fewer tried all of them.
  int tried_all = 0;
  double verification_per_candidate = 0;
  for (std::size_t i = 0; i < n; ++i) {
    if (run.verified_pairs[i] < options.max_verified_pairs && run.candidates[i] > 0) {
      ++tried_all;
      verification_per_candidate +=
          (run.call_times[i].matching + run.call_times[i].verification) / run.candidates[i];
    }
  }
  if (tried_all > 0) verification_per_candidate /= tried_all;
  std::printf("pairs: %d of %zu photos verified fewer than %d pairs and so matched every "
              "candidate; for them matching + verification took %.1f ms per candidate\n",
              tried_all, n, options.max_verified_pairs, verification_per_candidate);
  std::printf("memory: RSS %.0f MB before the engine; during the run:", rss_before_mb);
  for (const auto& [index, mb] : rss_samples) std::printf(" %d: %.0f MB,", index, mb);
  std::printf(" peak (VmHWM%s) %.0f MB; ru_maxrss (whole process, rendering included) %.0f "
              "MB; %ld page faults (malloc policy %s)\n",
              run.peak_reset ? ", reset before the engine" : "", run.peak_mb, run.maxrss_mb,
              run.page_faults, malloc_policy ? "applied" : "refused: glibc's defaults");
  if (errors) {
    std::printf("accuracy: %d centres compared, RMSE after Sim3 %.3f m = %.4f of the mean "
                "distance to the building (%.1f m); median %.3f m, max %.3f m\n",
                errors->num_compared, errors->rmse, errors->rmse / mean_distance,
                mean_distance, errors->median, errors->max);
  } else {
    std::printf("accuracy: too few registered images to align\n");
  }
  if (!calibrated) {
    std::printf("focal length: final %.1f px, true %.1f px, relative error %+.4f (start %.0f "
                "px%s)\n",
                final_focal, focal, focal_error, options.unknown_focal_factor * width,
                FromPairsText(run).c_str());
  }

  nlohmann::json json = {
      {"bench", "photos"},
      {"photos", num_photos},
      {"width", width},
      {"height", height},
      {"calibrated", calibrated},
      {"seed", seed},
      {"registered", run.model.NumRegisteredImages()},
      {"pending", run.pending},
      {"points", run.model.NumPoints3D()},
      {"mean_reprojection_error_px", run.model.MeanReprojectionError()},
      {"render_median_ms", Median(render_ms)},
      {"wall_s", run.wall_s},
      {"finish_s", run.finish_s},
      {"all_stages_ms", all_stats},
      {"engine_ms", engine_stats},
      {"growth_all_stages_last50_over_50_100", growth},
      {"growth_engine_last50_over_50_100", engine_growth},
      {"early", early},
      {"late", late},
      {"rss_before_mb", rss_before_mb},
      {"rss_mb", rss},
      {"peak_rss_mb", run.peak_mb},
      {"ru_maxrss_mb", run.maxrss_mb},
      {"page_faults", run.page_faults},
      {"malloc_policy", malloc_policy},
      {"mean_distance_m", mean_distance},
      {"center_rmse_m", errors ? errors->rmse : -1.0},
      {"center_rmse_relative", errors ? errors->rmse / mean_distance : -1.0},
      {"true_focal_px", focal},
      {"final_focal_px", final_focal},
      {"focal_relative_error", calibrated ? 0.0 : focal_error},
      {"focal_length_from_pairs_px", run.focal_length_from_pairs.value_or(0)},
      {"photos_matching_every_candidate", tried_all},
      {"match_and_verify_ms_per_candidate", verification_per_candidate}};
  if (profile) json["profile"] = Profile(frames, camera, options);
  if (real_sets) json["real_sets"] = RunRealSets(data);
  std::cout << json.dump() << "\n";
  if (!keep) fs::remove_all(dir);
  return 0;
}
