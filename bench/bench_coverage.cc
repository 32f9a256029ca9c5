// Does the coverage surface mark what was not photographed, and do its
// suggestions fix it? On rendered captures of bench_photos' building (exact
// geometry and poses), a photographer walks a ring around it at 20 m:
//
//   skip     skipping every stop from which the north wall (y = +6 m) can be
//            seen: that wall is never photographed;
//   single   the same, and three shots of the north wall from one place
//            (half a degree apart on the ring): seen, under too narrow an
//            angle.
//
//   bench_coverage [--scenarios skip,single] [--follow N] [--megapixels MP]
//                  [--seed S] [--supersampling K] [--work DIR]
//
// After the ring (the engine given the true K, fed unpaced as `flysfm batch`
// feeds it), the model is aligned to the world by the Sim3 of its camera
// centres, and each face of the coverage surface is judged again from the
// truth: the true cameras that face it (within the incidence limit), see its
// centroid in their image and are not blocked by the building's facets,
// under the same rule of views and angle. It prints, by area and over the
// faces a photographer can reach (undersides apart): the precision and
// recall of the under-covered faces against that truth, and the share of
// the north wall's faces marked under-covered. Then it follows the
// suggestions: the first suggested viewpoint is rendered at its pose (in
// the world, through the Sim3), fed to the same engine, the surface
// measured again, up to --follow shots or until 95 % of the surface is well
// covered. Also printed: the surface's time after each shot (median and the
// growth of the last third over the first). Ends with one line of JSON.

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <map>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include "bench/bench_session.h"
#include "bench/photo_session.h"
#include "core/engine.h"
#include "geometry/statistics.h"
#include "io/evaluation/evaluation.h"
#include "quality/coverage.h"

namespace flysfm {
namespace {

namespace fs = std::filesystem;

struct Flags {
  std::vector<std::string> scenarios = {"skip", "single"};
  int follow = 10;
  double megapixels = 6;
  int seed = 1;
  int supersampling = 1;
  std::string work;
};

int PhotoWidth(double megapixels) { return int(std::lround(std::sqrt(megapixels * 1e6 * 1.5))); }

std::string ShotName(const char* prefix, int index) {
  char name[48];
  std::snprintf(name, sizeof(name), "%s_%04d.jpg", prefix, index);
  return name;
}

// The ring every 10 degrees at 20 m, 1.6 m high, without the stops that see
// the north wall (y = 6 m: a stop at angle a is north of it for
// 20 sin(a) > 6, between 17.5 and 162.5 degrees); `single` adds three stops
// facing it from one place.
std::vector<RingStop> Stops(const std::string& scenario) {
  std::vector<RingStop> stops;
  int index = 0;
  for (int degrees = -180; degrees < 180; degrees += 10) {
    if (degrees > 10 && degrees < 170) continue;
    stops.push_back({ShotName("ring", index++), double(degrees), 20.0, 1.6});
  }
  if (scenario == "single") {
    for (const double degrees : {89.5, 90.0, 90.5}) {
      stops.push_back({ShotName("north", index++), degrees, 20.0, 1.6});
    }
  }
  return stops;
}

// Whether the segment from `from` to `to` passes through a facet.
bool Blocked(const Eigen::Vector3d& from, const Eigen::Vector3d& to,
             const std::vector<BuildingFacet>& facets) {
  const Eigen::Vector3d d = to - from;
  for (const BuildingFacet& facet : facets) {
    const Eigen::Vector3d normal = facet.axis_u.cross(facet.axis_v);
    const double denominator = normal.dot(d);
    if (std::abs(denominator) < 1e-12) continue;
    const double t = normal.dot(facet.origin - from) / denominator;
    if (t <= 1e-6 || t >= 1 - 1e-6) continue;
    const Eigen::Vector3d hit = from + t * d - facet.origin;
    // Coordinates along u and v (they are orthogonal in this scene).
    const double a = hit.dot(facet.axis_u) / facet.axis_u.squaredNorm();
    const double b = hit.dot(facet.axis_v) / facet.axis_v.squaredNorm();
    if (a > 0 && a < 1 && b > 0 && b < 1) return true;
  }
  return false;
}

// A face judged from the truth.
struct TruthOfFace {
  int views = 0;
  double max_angle_deg = 0;
  bool under = false;
};

TruthOfFace JudgeFace(const Coverage::Face& face, const Sim3d& world_from_model,
                      const std::vector<Shot>& shots, const Camera& camera,
                      const std::vector<BuildingFacet>& facets, const Coverage::Options& rule) {
  const Eigen::Vector3d centroid =
      world_from_model * ((face.corners[0] + face.corners[1] + face.corners[2]) / 3);
  const Eigen::Vector3d normal = world_from_model.rotation * face.normal;
  const double cos_incidence = std::cos(rule.max_incidence_deg * M_PI / 180);
  std::vector<Eigen::Vector3d> rays;
  for (const Shot& shot : shots) {
    const Eigen::Vector3d center = ProjectionCenter(shot.cam_from_world);
    const Eigen::Vector3d to_camera = center - centroid;
    const double distance = to_camera.norm();
    if (normal.dot(to_camera) < cos_incidence * distance) continue;
    const Eigen::Vector3d in_cam =
        shot.cam_from_world.rotation * centroid + shot.cam_from_world.translation;
    if (in_cam.z() <= 0) continue;
    const Eigen::Vector2d pixel = camera.ImgFromCam(in_cam);
    if (pixel.x() < 0 || pixel.y() < 0 || pixel.x() >= camera.width ||
        pixel.y() >= camera.height) {
      continue;
    }
    // From 5 cm off the face: the surface lies within centimetres of the
    // facets it stands for.
    if (Blocked(centroid + 0.05 * to_camera / distance, center, facets)) continue;
    rays.push_back(to_camera / distance);
  }
  TruthOfFace truth;
  truth.views = int(rays.size());
  for (std::size_t i = 0; i < rays.size(); ++i) {
    for (std::size_t j = i + 1; j < rays.size(); ++j) {
      truth.max_angle_deg = std::max(
          truth.max_angle_deg, std::atan2(rays[i].cross(rays[j]).norm(), rays[i].dot(rays[j])) *
                                   180 / M_PI);
    }
  }
  truth.under = truth.views < rule.min_views || truth.max_angle_deg < rule.min_angle_deg;
  return truth;
}

struct Judgement {
  double precision = 0;
  double recall = 0;
  double north_marked = 0;  // share of the north wall's face area marked under-covered
  double north_area = 0;
};

Judgement Judge(const Coverage& coverage, const Sim3d& world_from_model,
                const std::vector<Shot>& shots, const Camera& camera) {
  const std::vector<BuildingFacet> facets = BuildingFacets();
  double both = 0, predicted = 0, truly = 0, north_under = 0;
  Judgement judgement;
  for (const Coverage::Face& face : coverage.faces()) {
    if (face.face_class == Coverage::FaceClass::kUnderside) continue;
    // Not well covered, whatever the reason (few views, a narrow angle, out
    // of reach from where the photographer stood).
    const bool marked = face.face_class != Coverage::FaceClass::kWellCovered;
    const TruthOfFace truth =
        JudgeFace(face, world_from_model, shots, camera, facets, coverage.options());
    // Areas in square metres.
    const double area = face.area * world_from_model.scale * world_from_model.scale;
    if (marked) predicted += area;
    if (truth.under) truly += area;
    if (marked && truth.under) both += area;
    const Eigen::Vector3d centroid =
        world_from_model * ((face.corners[0] + face.corners[1] + face.corners[2]) / 3);
    const Eigen::Vector3d normal = world_from_model.rotation * face.normal;
    if (std::abs(centroid.y() - 6) < 0.5 && normal.y() > 0.8 && std::abs(centroid.x()) < 8 &&
        centroid.z() > 0 && centroid.z() < 8) {
      judgement.north_area += area;
      if (marked) north_under += area;
    }
  }
  judgement.precision = predicted > 0 ? both / predicted : 0;
  judgement.recall = truly > 0 ? both / truly : 0;
  judgement.north_marked = judgement.north_area > 0 ? north_under / judgement.north_area : 0;
  return judgement;
}

// The pose in the world of a pose in the model: x_cam = R (x_model) + t and
// x_model = world_from_model^-1 x_world, the camera frame scaled by s.
Rigid3d WorldPose(const Rigid3d& cam_from_model, const Sim3d& world_from_model) {
  const Eigen::Matrix3d r_model = cam_from_model.rotation.toRotationMatrix();
  const Eigen::Matrix3d r_sim = world_from_model.rotation.toRotationMatrix();
  const Eigen::Matrix3d rotation = r_model * r_sim.transpose();
  const Eigen::Vector3d translation =
      world_from_model.scale * cam_from_model.translation - rotation * world_from_model.translation;
  return Rigid3d(rotation, translation);
}

nlohmann::json RunScenario(const Flags& flags, const fs::path& work, const std::string& scenario,
                           const std::string& camera_text) {
  const int width = PhotoWidth(flags.megapixels);
  const Camera camera = Camera::FromString(camera_text, width, width * 2 / 3);
  const std::vector<RingStop> stops = Stops(scenario);
  const fs::path dir = work / scenario;
  std::ostringstream plan;
  plan.precision(9);
  for (const RingStop& stop : stops) plan << stop.name << ' ' << stop.angle_deg << ';';
  PrepareRenderFolder(dir, std::uint32_t(flags.seed), camera, flags.supersampling,
                      "coverage " + plan.str());
  std::vector<Shot> shots = MakeRingShots(stops, std::uint32_t(flags.seed));
  RenderPhotoSession(shots, camera, std::uint32_t(flags.seed), flags.supersampling, dir, 2);
  std::vector<Frame> frames;
  std::map<std::string, Eigen::Vector3d> truth;
  for (const Shot& shot : shots) {
    Frame frame;
    frame.name = shot.name;
    frame.path = dir / shot.name;
    frames.push_back(frame);
    truth[shot.name] = ProjectionCenter(shot.cam_from_world);
  }

  std::printf("\n%s: %zu shots\n", scenario.c_str(), shots.size());
  std::fflush(stdout);
  Engine engine(Engine::Options(), Camera::FromString(camera_text, 0, 0));
  Coverage coverage;
  std::vector<double> coverage_ms;
  bench::SessionOptions options;
  options.run.print = false;
  options.run.between_images = RunLoop::Options::BetweenImages::kNothing;
  // The surface after each shot, as the run loop measures it with its
  // outputs: its time is what a shot adds.
  options.on_image = [&](const Engine& e, const std::vector<ImageResult>&, const StageTimes&,
                         double) {
    coverage.Update(e.reconstruction());
    coverage_ms.push_back(coverage.summary().ms);
  };
  const bench::Session session = bench::RunSession(&engine, frames, options);
  coverage.Update(engine.reconstruction());

  const std::optional<PositionErrors> errors = CompareCentersByName(engine.reconstruction(), truth);
  nlohmann::json json = {{"scenario", scenario},
                         {"shots", shots.size()},
                         {"registered", engine.reconstruction().NumRegisteredImages()}};
  if (!errors) {
    std::printf("  fewer than 3 registered shots: nothing to judge\n");
    return json;
  }
  const Judgement judgement = Judge(coverage, errors->reference_from_estimate, shots, camera);
  const std::size_t third = coverage_ms.size() / 3;
  const double growth = third > 0 ? Median(std::vector<double>(coverage_ms.end() - third,
                                                               coverage_ms.end())) /
                                        Median(std::vector<double>(coverage_ms.begin(),
                                                                   coverage_ms.begin() + third))
                                  : 0;
  std::printf("  %zu registered, centre RMSE %.1f mm; surface %zu faces from %zu points, "
              "well covered %.1f %%\n",
              engine.reconstruction().NumRegisteredImages(), 1000 * errors->rmse,
              coverage.summary().faces, coverage.summary().points_used,
              100 * coverage.summary().well_covered_share);
  std::printf("  under-covered against the truth: precision %.3f, recall %.3f; north wall "
              "%.0f m2 of faces, %.1f %% marked\n",
              judgement.precision, judgement.recall, judgement.north_area,
              100 * judgement.north_marked);
  std::printf("  surface time per shot: median %.1f ms, max %.1f ms, growth %.2f\n",
              Median(coverage_ms), coverage_ms.empty() ? 0.0 : *std::max_element(
                                                                   coverage_ms.begin(),
                                                                   coverage_ms.end()),
              growth);
  for (const Coverage::Suggestion& suggestion : coverage.suggestions()) {
    std::printf("  suggestion: %s\n", suggestion.reason.c_str());
  }
  json["center_rmse_m"] = errors->rmse;
  json["faces"] = coverage.summary().faces;
  json["well_covered_share"] = coverage.summary().well_covered_share;
  json["precision"] = judgement.precision;
  json["recall"] = judgement.recall;
  json["north_wall_marked"] = judgement.north_marked;
  json["coverage_ms"] = bench::Stats(coverage_ms);
  json["coverage_growth"] = growth;
  json["all_stages_ms"] = bench::Stats(session.all_stages_ms);

  // Following the suggestions.
  nlohmann::json followed = nlohmann::json::array();
  const fs::path follow_dir = work / (scenario + "_followed");
  fs::remove_all(follow_dir);
  for (int k = 0; k < flags.follow && !coverage.suggestions().empty() &&
                  coverage.summary().well_covered_share < 0.95;
       ++k) {
    const std::optional<PositionErrors> now =
        CompareCentersByName(engine.reconstruction(), truth);
    if (!now) break;
    const Coverage::Suggestion suggestion = coverage.suggestions().front();
    Shot shot;
    shot.name = ShotName("suggested", k);
    shot.cam_from_world = WorldPose(suggestion.cam_from_world, now->reference_from_estimate);
    PrepareRenderFolder(follow_dir, std::uint32_t(flags.seed), camera, flags.supersampling,
                        "suggested");
    RenderPhotoSession({shot}, camera, std::uint32_t(flags.seed), flags.supersampling,
                       follow_dir, 2);
    Frame frame;
    frame.name = shot.name;
    frame.path = follow_dir / shot.name;
    truth[shot.name] = ProjectionCenter(shot.cam_from_world);
    shots.push_back(shot);
    bench::SessionOptions one;
    one.run.print = false;
    one.run.between_images = RunLoop::Options::BetweenImages::kNothing;
    const bench::Session added = bench::RunSession(&engine, {frame}, one);
    const bool registered = !added.run.results.empty() &&
                            added.run.results.front().result.status == ImageStatus::kRegistered;
    const std::string outcome =
        added.run.results.empty()
            ? "no result"
            : std::string(ImageStatusName(added.run.results.front().result.status)) +
                  (added.run.results.front().result.reason.empty()
                       ? ""
                       : " (" + added.run.results.front().result.reason + ")");
    coverage.Update(engine.reconstruction());
    const Eigen::Vector3d centre = ProjectionCenter(shot.cam_from_world);
    std::printf("  followed %d: %s -> at (%.1f, %.1f, %.1f) m, %s; well covered %.1f %%\n",
                k + 1, suggestion.reason.c_str(), centre.x(), centre.y(), centre.z(),
                outcome.c_str(),
                100 * coverage.summary().well_covered_share);
    std::fflush(stdout);
    followed.push_back({{"reason", suggestion.reason},
                        {"registered", registered},
                        {"position_m", {centre.x(), centre.y(), centre.z()}},
                        {"well_covered_share", coverage.summary().well_covered_share}});
  }
  json["followed"] = followed;
  return json;
}

}  // namespace
}  // namespace flysfm

int main(int argc, char** argv) {
  using namespace flysfm;
  Flags flags;
  CLI::App app("Coverage surface against the truth, and following its suggestions");
  app.add_option("--scenarios", flags.scenarios, "skip, single")->delimiter(',');
  app.add_option("--follow", flags.follow, "Suggested shots to follow, at most")
      ->capture_default_str();
  app.add_option("--megapixels", flags.megapixels, "Photo size")->capture_default_str();
  app.add_option("--seed", flags.seed, "Texture and hand jitter seed")->capture_default_str();
  app.add_option("--supersampling", flags.supersampling, "Render supersampling")
      ->capture_default_str();
  app.add_option("--work", flags.work, "Folder for the renders (kept; default: a temp folder)");
  CLI11_PARSE(app, argc, argv);
  const fs::path work =
      flags.work.empty() ? fs::temp_directory_path() / "flysfm_bench_coverage" : fs::path(flags.work);
  fs::create_directories(work);
  const std::string camera_text = PhotoSessionCamera(PhotoWidth(flags.megapixels));
  nlohmann::json results = nlohmann::json::array();
  for (const std::string& scenario : flags.scenarios) {
    if (scenario != "skip" && scenario != "single") {
      std::fprintf(stderr, "bench_coverage: unknown scenario %s\n", scenario.c_str());
      return 2;
    }
    results.push_back(RunScenario(flags, work, scenario, camera_text));
  }
  std::printf("%s\n", nlohmann::json({{"bench", "coverage"}, {"scenarios", results}}).dump().c_str());
  return 0;
}
