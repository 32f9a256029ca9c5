// The engine on a long photo session rather than a video: a DSLR walking
// around a building (synthetic, exact ground truth), 6 MP by default
// (--megapixels 24 for 6000x4000), 300 shots 1-3 m apart on several loops at
// different heights and distances, the later loops revisiting the first one.
// Shows whether the per-image time stays flat and memory stays bounded as the
// session grows, how long the end takes, and the accuracy reached (camera
// centres after Sim3; the self-calibrated focal length when the camera is
// unknown). Ends with one line of JSON.
//
//   bench_photos [--photos N] [--megapixels 6|24] [--calibrated] [--seed S]
//                [--supersampling K] [--work DIR] [--window-budget MB] [--profile]
//                [--data DIR] [--no-real] [--glibc-malloc-defaults] [--out DIR]
//
// After the synthetic session, the same per-photo figures on the real 6 MP
// sets of --data: fountain-P11 and sceaux_castle, each with its K given and
// without (--no-real skips them).
//
// Each view is rendered by io/synthetic's renderer, written as a JPEG
// (quality 92, no EXIF, so the uncalibrated engine must guess the focal
// length) and fed as a file through the run loop, as `flysfm batch` feeds a
// folder. Rendering is timed apart; it is not the engine's. With --work the
// JPEGs are kept there and reused by a later run with the same seed and size
// (rendering 300 photos takes minutes). --window-budget sets
// LsmImageStore::Options::window_budget_megabytes. --glibc-malloc-defaults
// leaves the allocator as glibc sets it, the baseline of core/malloc_policy.h.
// --profile adds bench/photo_profile.h's offline look at verification.
// --out DIR runs the session with an output folder, as `flysfm batch --out`
// does, so that the quality measures and the coverage surface are kept
// current, and prints their cost per photo from DIR/log.jsonl (outside the
// engine's all-stages time), its growth and the surface's updates.

#include <unistd.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <numeric>
#include <optional>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include "bench/bench_session.h"
#include "bench/photo_profile.h"
#include "bench/photo_session.h"
#include "core/engine.h"
#include "core/malloc_policy.h"
#include "geometry/statistics.h"
#include "io/evaluation/evaluation.h"
#include "io/formats/trajectory.h"
#include "io/sources/image_source.h"
#include "quality/quality_tracker.h"
#include "tests/testing/datasets.h"

namespace flysfm {
namespace {

namespace fs = std::filesystem;

struct Flags {
  int num_photos = 300;
  int megapixels = 6;
  bool calibrated = false;
  bool profile = false;
  int seed = 1;
  int supersampling = 1;
  std::string work;
  int window_budget_mb = LsmImageStore::Options().window_budget_megabytes;
  std::string data;
  bool no_real = false;
  bool glibc_malloc_defaults = false;
  bool render_only = false;
  std::string out;
};

// ", the initial pairs' F gave N px" when they replaced the guess.
std::string FromPairsText(const bench::Session& session) {
  if (!session.focal_length_from_pairs) return "";
  char text[64];
  std::snprintf(text, sizeof(text), ", the initial pairs' F gave %.1f px",
                *session.focal_length_from_pairs);
  return text;
}

double FinalFocal(const Reconstruction& model) {
  double focal = 0;
  for (const auto& [camera_id, camera] : model.cameras()) focal = camera.MeanFocalLength();
  return focal;
}

// A real photo set, with or without its K: the same per-photo figures (too
// few photos for a growth), the centres against ground truth where there is
// one, the focal length against K.
nlohmann::json RunRealSet(const testing::PhotoSet& set, bool k_given) {
  const std::string name = set.name + (k_given ? ", K given" : ", without K");
  std::optional<Camera> known_camera;
  if (k_given) known_camera = Camera::FromString(set.camera, 0, 0);
  Engine engine(Engine::Options(), known_camera);
  bench::SessionOptions options;
  options.run.print = false;
  options.run.between_images = RunLoop::Options::BetweenImages::kNothing;
  const bench::Session session = bench::RunSession(&engine, set.frames, options);
  const Reconstruction& model = engine.reconstruction();
  const double final_focal = FinalFocal(model);
  const std::optional<PositionErrors> errors =
      set.cam_from_world.empty() ? std::nullopt : CompareCentersByName(model, set.Centres());
  std::printf("%s: registered %zu/%zu; ", name.c_str(), model.NumRegisteredImages(),
              set.frames.size());
  if (errors) std::printf("centres RMSE %.2f mm; ", errors->rmse * 1000);
  std::printf("focal %.1f px (K %.1f, %+.2f %%%s)\n", final_focal, set.focal_length,
              100 * (final_focal / set.focal_length - 1), FromPairsText(session).c_str());
  bench::PrintSessionFigures(session, ("  " + name).c_str());
  nlohmann::json json = bench::SessionJson(session);
  json.update({{"name", name},
               {"calibrated", k_given},
               {"photos", set.frames.size()},
               {"registered", model.NumRegisteredImages()},
               {"center_rmse_m", errors ? errors->rmse : -1.0},
               {"final_focal_px", final_focal},
               {"focal_length_from_pairs_px", session.focal_length_from_pairs.value_or(0)},
               {"true_focal_px", set.focal_length}});
  return json;
}

// fountain-P11 (Strecha's cameras) and sceaux_castle (its K.txt, no poses),
// each with its K given and without (sceaux keeps its EXIF focal length).
nlohmann::json RunRealSets(const fs::path& data) {
  std::printf("\nreal photo sets in %s, fed as `flysfm batch` does:\n", data.c_str());
  nlohmann::json sets = nlohmann::json::array();
  for (const testing::PhotoSet& set : {testing::FountainP11(data), testing::SceauxCastle(data)}) {
    for (const bool k_given : {true, false}) sets.push_back(RunRealSet(set, k_given));
  }
  return sets;
}

// The rendered session, its photos in `dir` (rendered now where missing).
struct RenderedSession {
  Camera camera;
  std::string camera_text;
  std::vector<Frame> frames;
  std::map<std::string, Eigen::Vector3d> true_centres;
  double mean_distance_m = 0;
  std::vector<double> render_ms;
};

RenderedSession Render(const Flags& flags, const fs::path& dir) {
  RenderedSession session;
  // 3:2 sensor; a 30 mm-equivalent lens (36 mm film width): f = 30/36 width.
  const int width = flags.megapixels == 24 ? 6000 : 3000;
  session.camera_text = PhotoSessionCamera(width);
  session.camera = Camera::FromString(session.camera_text, width, width * 2 / 3);
  PrepareRenderFolder(dir, std::uint32_t(flags.seed), session.camera, flags.supersampling);
  const std::vector<Shot> shots = MakePhotoSession(flags.num_photos, std::uint32_t(flags.seed));
  // On both cores (the engine does not run yet); not engine time.
  session.render_ms = RenderPhotoSession(shots, session.camera, std::uint32_t(flags.seed),
                                         flags.supersampling, dir, 2);
  for (int i = 0; i < flags.num_photos; ++i) {
    Frame frame;
    frame.name = shots[i].name;
    frame.path = dir / shots[i].name;
    frame.timestamp = i;
    session.frames.push_back(frame);
    session.true_centres[shots[i].name] = ProjectionCenter(shots[i].cam_from_world);
    session.mean_distance_m += shots[i].distance_to_building / flags.num_photos;
  }
  return session;
}

// One line per photo, and the memory every 50 photos.
void PrintPhoto(const Engine& engine, const std::vector<ImageResult>& out,
                const StageTimes& times, double engine_ms, int index, int num_photos,
                nlohmann::json* rss) {
  std::printf("[%4d] %-16s %-10s all stages %6.0f ms (decode %4.0f, features %4.0f, "
              "verification %5.0f, lsm %5.0f, ba %5.0f), engine %6.0f ms, %2d/%2d pairs, "
              "model %d img / %d pts%s%s\n",
              index, out.front().name.c_str(), ImageStatusName(out.front().status), times.total,
              times.decode, times.features, times.verification, times.lsm, times.ba, engine_ms,
              out.front().num_verified_pairs, out.front().num_candidates,
              out.back().model_images, out.back().model_points,
              out.front().reason.empty() ? "" : "  ", out.front().reason.c_str());
  if (index % 50 == 0 || index == num_photos) {
    const double mb = bench::ProcStatusMb("VmRSS");
    (*rss)[std::to_string(index)] = mb;
    std::printf("       RSS after %d photos: %.0f MB (LSM store: windows %.0f MB, whole images "
                "%.0f MB)\n",
                index, mb, engine.lsm_images().window_bytes() / 1048576.0,
                engine.lsm_images().whole_bytes() / 1048576.0);
  }
  std::fflush(stdout);
}

// Early (photos 50-100) against late (the last 50): the growth of per-photo
// time, stage by stage.
nlohmann::json GrowthFigures(const bench::Session& session) {
  const std::size_t n = session.all_stages_ms.size();
  const std::size_t late_begin = n >= 50 ? n - 50 : 0;
  const nlohmann::json early = bench::StageMedians(session.call_times, 50, 100);
  const nlohmann::json late = bench::StageMedians(session.call_times, late_begin, n);
  const double growth = bench::Growth(session.all_stages_ms, 50, 50);
  const double engine_growth = bench::Growth(session.engine_ms, 50, 50);
  std::printf("growth, median of the last 50 / photos 50-100: all stages %.2f, engine %.2f\n",
              growth, engine_growth);
  std::printf("  %-14s %12s %12s\n", "stage (ms)", "photos 50-100", "last 50");
  for (const auto& [name, stage] : StageTimes::Stages()) {
    std::printf("  %-14s %12.1f %12.1f\n", name, early[name].get<double>(),
                late[name].get<double>());
  }
  return {{"growth_all_stages_last50_over_50_100", growth},
          {"growth_engine_last50_over_50_100", engine_growth},
          {"early_stage_median_ms", early},
          {"late_stage_median_ms", late}};
}

// The engine verifies candidates in retrieval order until max_verified_pairs
// verify: a photo with fewer tried all of them.
nlohmann::json PairFigures(const bench::Session& session, const Engine::Options& options) {
  int tried_all = 0;
  double per_candidate_ms = 0;
  for (std::size_t i = 0; i < session.call_times.size(); ++i) {
    if (session.verified_pairs[i] < options.max_verified_pairs && session.candidates[i] > 0) {
      ++tried_all;
      per_candidate_ms += (session.call_times[i].matching + session.call_times[i].verification) /
                          session.candidates[i];
    }
  }
  if (tried_all > 0) per_candidate_ms /= tried_all;
  std::printf("pairs: %d of %zu photos verified fewer than %d pairs and so matched every "
              "candidate; for them matching + verification took %.1f ms per candidate\n",
              tried_all, session.call_times.size(), options.max_verified_pairs,
              per_candidate_ms);
  return {{"photos_matching_every_candidate", tried_all},
          {"match_and_verify_ms_per_candidate", per_candidate_ms}};
}

nlohmann::json AccuracyFigures(const Flags& flags, const RenderedSession& rendered,
                               const Reconstruction& model, const bench::Session& session) {
  const std::optional<PositionErrors> errors =
      CompareCentersByName(model, rendered.true_centres);
  const double focal = rendered.camera.params[0];
  const double final_focal = FinalFocal(model);
  if (errors) {
    std::printf("accuracy: %d centres compared, RMSE after Sim3 %.3f m = %.4f of the mean "
                "distance to the building (%.1f m); median %.3f m, max %.3f m\n",
                errors->num_compared, errors->rmse, errors->rmse / rendered.mean_distance_m,
                rendered.mean_distance_m, errors->median, errors->max);
  } else {
    std::printf("accuracy: too few registered images to align\n");
  }
  if (!flags.calibrated) {
    std::printf("focal length: final %.1f px, true %.1f px, relative error %+.4f (start %.0f "
                "px%s)\n",
                final_focal, focal, final_focal / focal - 1,
                Engine::Options().unknown_focal_factor * rendered.camera.width,
                FromPairsText(session).c_str());
  }
  return {{"registered", model.NumRegisteredImages()},
          {"points", model.NumPoints3D()},
          {"mean_reprojection_error_px", model.MeanReprojectionError()},
          {"mean_distance_m", rendered.mean_distance_m},
          {"center_rmse_m", errors ? errors->rmse : -1.0},
          {"center_rmse_relative", errors ? errors->rmse / rendered.mean_distance_m : -1.0},
          {"true_focal_px", focal},
          {"final_focal_px", final_focal},
          {"focal_relative_error", flags.calibrated ? 0.0 : final_focal / focal - 1},
          {"focal_length_from_pairs_px", session.focal_length_from_pairs.value_or(0)}};
}

double MeanOf(const std::vector<double>& values, std::size_t begin, std::size_t end) {
  end = std::min(end, values.size());
  begin = std::min(begin, end);
  if (begin == end) return 0;
  return std::accumulate(values.begin() + std::ptrdiff_t(begin),
                         values.begin() + std::ptrdiff_t(end), 0.0) / double(end - begin);
}

// What the photographer's feedback adds to each photo (--out): the quality
// tracker's update and the coverage surface's, from the first log.jsonl
// record of each photo (the one of its arrival, which carries them). The
// surface is measured on some photos only (at most every refresh and a
// tenth of the run), so besides the median the mean per photo (its
// amortised cost) and its growth, last 50 over photos 50-100.
nlohmann::json FeedbackFigures(const fs::path& out, const std::vector<Frame>& frames) {
  std::map<std::string, std::pair<double, double>> first;  // name -> quality, coverage ms
  std::ifstream log(out / "log.jsonl");
  for (std::string line; std::getline(log, line);) {
    const nlohmann::json record = nlohmann::json::parse(line, nullptr, false);
    if (record.is_discarded() || !record.contains("name") || !record.contains("ms")) continue;
    const nlohmann::json& ms = record["ms"];
    first.emplace(record["name"].get<std::string>(),
                  std::make_pair(ms.value("quality", 0.0), ms.value("coverage", 0.0)));
  }
  std::vector<double> quality, coverage, added, coverage_updates;
  for (const Frame& frame : frames) {
    const auto found = first.find(frame.name);
    if (found == first.end()) continue;
    quality.push_back(found->second.first);
    coverage.push_back(found->second.second);
    added.push_back(found->second.first + found->second.second);
    if (found->second.second > 0) coverage_updates.push_back(found->second.second);
  }
  const std::size_t n = added.size();
  const double mean_early = MeanOf(added, 50, 100);
  const double mean_late = MeanOf(added, n >= 50 ? n - 50 : 0, n);
  const double mean_growth = mean_early > 0 ? mean_late / mean_early : 0;
  const nlohmann::json added_stats = bench::Stats(added);
  std::printf("feedback (quality + coverage, outside the engine), %zu photos: per photo median "
              "%.1f ms, p95 %.1f ms, max %.1f ms, mean %.1f ms; quality median %.1f ms; surface "
              "measured on %zu photos, median %.1f ms, max %.1f ms; mean per photo over photos "
              "50-100 %.1f ms, last 50 %.1f ms (growth %.2f); median growth %.2f\n",
              n, added_stats["median"].get<double>(), added_stats["p95"].get<double>(),
              added_stats["max"].get<double>(), MeanOf(added, 0, n), Median(quality),
              coverage_updates.size(), Median(coverage_updates),
              coverage_updates.empty()
                  ? 0.0
                  : *std::max_element(coverage_updates.begin(), coverage_updates.end()),
              mean_early, mean_late, mean_growth, bench::Growth(added, 50, 50));
  return {{"photos_logged", n},
          {"added_ms", added_stats},
          {"added_mean_ms", MeanOf(added, 0, n)},
          {"quality_median_ms", Median(quality)},
          {"coverage_updates", coverage_updates.size()},
          {"coverage_update_ms", bench::Stats(coverage_updates)},
          {"added_mean_ms_50_100", mean_early},
          {"added_mean_ms_last50", mean_late},
          {"added_mean_growth", mean_growth},
          {"added_median_growth", bench::Growth(added, 50, 50)}};
}

// The distance along the ray from `origin` to the nearest facet it meets;
// nullopt when it meets none.
std::optional<double> NearestFacet(const Eigen::Vector3d& origin, const Eigen::Vector3d& direction,
                                   const std::vector<BuildingFacet>& facets) {
  std::optional<double> nearest;
  for (const BuildingFacet& facet : facets) {
    const Eigen::Vector3d normal = facet.axis_u.cross(facet.axis_v);
    const double denominator = normal.dot(direction);
    if (std::abs(denominator) < 1e-12) continue;
    const double t = normal.dot(facet.origin - origin) / denominator;
    if (t <= 0 || (nearest && t >= *nearest)) continue;
    const Eigen::Vector3d hit = origin + t * direction - facet.origin;
    // The scene's facets have orthogonal axes.
    const double a = hit.dot(facet.axis_u) / facet.axis_u.squaredNorm();
    const double b = hit.dot(facet.axis_v) / facet.axis_v.squaredNorm();
    if (a >= 0 && a <= 1 && b >= 0 && b <= 1) nearest = t;
  }
  return nearest;
}

// Do the uncertainties rank points and cameras by their true error (--out)?
// The model aligned to the truth by the Sim3 of the camera centres; a
// point's true error is how far it lies from the building along the rays
// from the true centres of the images observing it (their mean: the
// direction in which a point's uncertainty is largest, and free of the
// keypoints' own error, which a point cast from them would carry into the
// truth); a camera's, its aligned centre's distance from the true one.
// Spearman's rank correlation of each with its sigma, for one sigma source.
nlohmann::json Ranking(const Reconstruction& model, const RenderedSession& rendered,
                       const Sim3d& truth_from_model, QualityTracker::Options::Sigma source) {
  QualityTracker::Options options;
  options.sigma_source = source;
  QualityTracker tracker(options);
  tracker.Rebuild(model);
  const std::vector<BuildingFacet> facets = BuildingFacets();
  std::vector<double> point_sigmas, point_errors;
  for (const auto& [id, point] : model.points3D()) {
    const std::optional<PointQuality> quality = tracker.Point(id);
    if (!quality || !quality->sigma) continue;
    const Eigen::Vector3d aligned = truth_from_model * point.xyz;
    double error = 0;
    int hits = 0;
    for (const TrackElement& element : point.track) {
      const Eigen::Vector3d& centre = rendered.true_centres.at(model.image(element.image_id).name);
      const std::optional<double> along =
          NearestFacet(centre, (aligned - centre).normalized(), facets);
      if (!along) continue;
      error += std::abs((aligned - centre).norm() - *along);
      ++hits;
    }
    if (hits == 0) continue;
    point_sigmas.push_back(*quality->sigma);
    point_errors.push_back(error / hits);
  }
  std::vector<double> centre_sigmas, centre_errors;
  for (const auto& [image_id, quality] : tracker.Images()) {
    if (!quality.center_sigma) continue;
    const Image& image = model.image(image_id);
    centre_sigmas.push_back(*quality.center_sigma);
    centre_errors.push_back((truth_from_model * ProjectionCenter(*image.cam_from_world) -
                             rendered.true_centres.at(image.name))
                                .norm());
  }
  const double point_rho = SpearmanCorrelation(point_sigmas, point_errors).value_or(0);
  const double centre_rho = SpearmanCorrelation(centre_sigmas, centre_errors).value_or(0);
  std::printf("uncertainty ranking, sigma source %s: %zu points, Spearman(sigma, true error) "
              "%.3f (median true error %.2f mm); %zu cameras, Spearman(centre sigma, centre "
              "error) %.3f (median %.2f mm)\n",
              SigmaSourceName(source), point_sigmas.size(), point_rho,
              1000 * Median(point_errors), centre_sigmas.size(), centre_rho,
              1000 * Median(centre_errors));
  return {{"points", point_sigmas.size()},
          {"point_spearman", point_rho},
          {"point_median_error_m", Median(point_errors)},
          {"cameras", centre_sigmas.size()},
          {"camera_spearman", centre_rho},
          {"camera_median_error_m", Median(centre_errors)}};
}

// The ranking with each sigma source.
nlohmann::json RankingFigures(const Reconstruction& model, const RenderedSession& rendered) {
  const std::optional<PositionErrors> alignment =
      CompareCentersByName(model, rendered.true_centres);
  if (!alignment) return {{"checked", false}};
  nlohmann::json json = {{"checked", true}};
  for (const auto source :
       {QualityTracker::Options::Sigma::kFixed, QualityTracker::Options::Sigma::kModelRms,
        QualityTracker::Options::Sigma::kAPosteriori}) {
    json[SigmaSourceName(source)] =
        Ranking(model, rendered, alignment->reference_from_estimate, source);
  }
  return json;
}

// --render-only: the photos stay in `dir` for `flysfm batch` (scripts/
// bench_compare.sh runs two revisions on them), with their exact poses as a
// TUM trajectory (groundtruth.txt, camera-to-world; the timestamp of photo i
// is i, as a folder's images get theirs) and the camera (camera.txt, as
// --camera takes it).
int WriteGroundTruth(const RenderedSession& rendered, const Flags& flags, const fs::path& dir) {
  std::vector<StampedPose> poses;
  for (const Frame& frame : rendered.frames) {
    const Eigen::Vector3d centre = rendered.true_centres.at(frame.name);
    StampedPose pose;
    pose.timestamp = frame.timestamp;
    pose.world_from_cam.translation = centre;
    poses.push_back(pose);
  }
  WriteTumTrajectory(poses, dir / "groundtruth.txt");
  std::ofstream(dir / "camera.txt") << rendered.camera_text << "\n";
  std::printf("render-only: %d photos, groundtruth.txt and camera.txt in %s\n", flags.num_photos,
              dir.c_str());
  return 0;
}

int Main(const Flags& flags) {
  // As flysfm, before any thread starts: the engine as it runs there.
  const bool malloc_policy = !flags.glibc_malloc_defaults && ApplyMallocPolicy();
  // The folder of JPEGs: --work (kept, reused when its manifest matches) or
  // a temporary one (removed at the end).
  const fs::path dir = !flags.work.empty()
                           ? fs::path(flags.work)
                           : fs::temp_directory_path() /
                                 ("bench_photos_" + std::to_string(::getpid()));
  std::printf("bench_photos: %d photos of %d MP, %s; seed %d; photos in %s\n", flags.num_photos,
              flags.megapixels,
              flags.calibrated ? "CALIBRATED (the true K given, held fixed)"
                               : "UNCALIBRATED (focal guessed by the engine, self-calibrated)",
              flags.seed, dir.c_str());
  std::fflush(stdout);
  const RenderedSession rendered = Render(flags, dir);
  std::printf("render: %zu photos rendered (median %.0f ms each, one core), the others reused\n",
              rendered.render_ms.size(), Median(rendered.render_ms));
  if (flags.render_only) return WriteGroundTruth(rendered, flags, dir);

  Engine::Options options;
  options.lsm_images.window_budget_megabytes = flags.window_budget_mb;
  std::optional<Camera> known_camera;
  if (flags.calibrated) known_camera = Camera::FromString(rendered.camera_text, 0, 0);
  Engine engine(options, known_camera);
  const double rss_before_mb = bench::ProcStatusMb("VmRSS");
  nlohmann::json rss = nlohmann::json::object();
  bench::SessionOptions session_options;
  session_options.run.print = false;
  session_options.run.between_images = RunLoop::Options::BetweenImages::kNothing;
  if (!flags.out.empty()) {
    fs::remove_all(flags.out);
    session_options.run.out = flags.out;
  }
  int index = 0;
  session_options.on_image = [&](const Engine& engine, const std::vector<ImageResult>& out,
                                 const StageTimes& times, double engine_ms) {
    PrintPhoto(engine, out, times, engine_ms, ++index, flags.num_photos, &rss);
  };
  const bench::Session session = bench::RunSession(&engine, rendered.frames, session_options);
  const Reconstruction& model = engine.reconstruction();

  std::printf("\n%s, %d photos: registered %zu, %zu pending, %zu points\n",
              flags.calibrated ? "calibrated" : "uncalibrated", flags.num_photos,
              model.NumRegisteredImages(), engine.PendingImageNames().size(),
              model.NumPoints3D());
  bench::PrintSessionFigures(session, "session");
  nlohmann::json json = bench::SessionJson(session);
  json.update(GrowthFigures(session));
  json.update(PairFigures(session, options));
  std::printf("memory: RSS %.0f MB before the engine; malloc policy %s\n", rss_before_mb,
              malloc_policy ? "applied" : "refused: glibc's defaults");
  json.update(AccuracyFigures(flags, rendered, model, session));
  if (!flags.out.empty()) {
    json["feedback"] = FeedbackFigures(flags.out, rendered.frames);
    json["ranking"] = RankingFigures(model, rendered);
  }
  json.update({{"bench", "photos"},
               {"photos", flags.num_photos},
               {"width", rendered.camera.width},
               {"height", rendered.camera.height},
               {"calibrated", flags.calibrated},
               {"seed", flags.seed},
               {"pending", engine.PendingImageNames().size()},
               {"render_median_ms", Median(rendered.render_ms)},
               {"rss_before_mb", rss_before_mb},
               {"rss_mb", rss},
               {"malloc_policy", malloc_policy}});
  if (flags.profile) json["profile"] = bench::ProfilePhotoPairs(rendered.frames, rendered.camera, options);
  if (!flags.no_real) json["real_sets"] = RunRealSets(flags.data);
  std::cout << json.dump() << "\n";
  if (flags.work.empty()) fs::remove_all(dir);
  return 0;
}

}  // namespace
}  // namespace flysfm

int main(int argc, char** argv) {
  using namespace flysfm;
  Flags flags;
  CLI::App app("The engine on a long rendered photo session, then the real 6 MP sets");
  app.add_option("--photos", flags.num_photos, "Photos of the session")
      ->check(CLI::Range(10, 100000))
      ->capture_default_str();
  app.add_option("--megapixels", flags.megapixels, "6 (3000x2000) or 24 (6000x4000)")
      ->check(CLI::IsMember({6, 24}))
      ->capture_default_str();
  app.add_flag("--calibrated", flags.calibrated, "Give the engine the true K (held fixed)");
  app.add_option("--seed", flags.seed, "Path and texture seed")->capture_default_str();
  app.add_option("--supersampling", flags.supersampling, "Render supersampling")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  app.add_option("--work", flags.work, "Keep the rendered JPEGs here and reuse them");
  app.add_option("--window-budget", flags.window_budget_mb, "LSM window budget (MB)")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  app.add_flag("--profile", flags.profile, "Also the offline look at verification's cost");
  bench::AddDataOption(&app, &flags.data);
  app.add_flag("--no-real", flags.no_real, "Skip the real photo sets");
  app.add_flag("--glibc-malloc-defaults", flags.glibc_malloc_defaults,
               "Leave the allocator as glibc sets it (core/malloc_policy.h's baseline)");
  app.add_flag("--render-only", flags.render_only,
               "Only render the photos into --work, with groundtruth.txt and camera.txt, for "
               "`flysfm batch` (scripts/bench_compare.sh)");
  app.add_option("--out", flags.out,
                 "Run with this output folder (emptied first), the quality measures and "
                 "coverage surface kept current, and print their cost per photo");
  CLI11_PARSE(app, argc, argv);
  if (flags.render_only && flags.work.empty()) {
    std::fprintf(stderr, "bench_photos: --render-only needs --work DIR\n");
    return 2;
  }
  return Main(flags);
}
