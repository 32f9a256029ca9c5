#include "io/evaluation/evaluation.h"

#include <cmath>
#include <random>

#include <catch2/catch.hpp>

#include "core/scene_bundle.h"
#include "tests/testing/scene_reconstruction.h"

namespace flysfm {
namespace {

// Ten views of 400 points with 0.3 px of noise, adjusted by a global BA as
// the engine's model is: its poses are the least-squares ones.
struct AdjustedScene {
  testing::SyntheticScene scene;
  Reconstruction model;
  std::map<std::string, Rigid3d> true_poses;
};

AdjustedScene MakeAdjustedScene() {
  testing::SyntheticSceneOptions options;
  options.num_points = 400;
  options.noise_px = 0.3;
  options.seed = 11;
  AdjustedScene adjusted;
  adjusted.scene = testing::MakeSyntheticScene(options);
  adjusted.model = testing::ReconstructionFromScene(adjusted.scene).reconstruction;
  REQUIRE(AdjustGlobalBundle(BundleAdjuster::Options(), &adjusted.model)
              .summary.IsSolutionUsable());
  for (int i = 0; i < int(adjusted.scene.cams_from_world.size()); ++i) {
    adjusted.true_poses["image" + std::to_string(i)] = adjusted.scene.cams_from_world[i];
  }
  return adjusted;
}

TEST_CASE("Exact poses fit a model's observations as well as its own adjusted poses") {
  const AdjustedScene adjusted = MakeAdjustedScene();
  const std::optional<PoseFit> fit =
      FitObservationsToPoses(adjusted.model, adjusted.true_poses);
  REQUIRE(fit);
  CHECK(fit->num_observations == int(adjusted.model.NumObservations()));
  // Least squares leaves sigma^2 per coordinate times the redundancy's share:
  // each point takes 3 of its 2 x (track length) coordinates. The median of
  // the error lengths is Rayleigh's, sqrt(ln 2) of the RMS.
  const double redundancy = 1 - 3 / (2 * adjusted.model.MeanTrackLength());
  const double rms = 0.3 * std::sqrt(2 * redundancy);
  CHECK(fit->truth_rms_px == Approx(rms).epsilon(0.05));
  CHECK(fit->truth_median_px == Approx(rms * std::sqrt(std::log(2.0))).epsilon(0.05));
  // The adjusted poses fit the noise a little better than the true ones
  // (their 6 parameters an image), by far less than the noise.
  CHECK(fit->model_rms_px <= fit->truth_rms_px);
  CHECK(fit->truth_rms_px <= 1.05 * fit->model_rms_px);
}

TEST_CASE("Poses off by a fraction of a percent of the distance fit the observations worse") {
  const AdjustedScene adjusted = MakeAdjustedScene();
  // Each centre moved by 1 cm at 5 m (0.2 %), as a ground truth of its own
  // error: 1 px at a 500 px focal length, less what the points' own shift
  // absorbs.
  std::mt19937 rng(12);
  std::map<std::string, Rigid3d> perturbed = adjusted.true_poses;
  for (auto& [name, cam_from_world] : perturbed) {
    cam_from_world.translation += 0.01 * testing::RandomUnitVector(rng);
  }
  const std::optional<PoseFit> exact = FitObservationsToPoses(adjusted.model, adjusted.true_poses);
  const std::optional<PoseFit> off = FitObservationsToPoses(adjusted.model, perturbed);
  REQUIRE(exact);
  REQUIRE(off);
  CHECK(off->truth_median_px > 1.5 * exact->truth_median_px);
  CHECK(off->model_median_px == exact->model_median_px);
}

TEST_CASE("Images without a true pose are left out of the fit") {
  const AdjustedScene adjusted = MakeAdjustedScene();
  CHECK_FALSE(FitObservationsToPoses(adjusted.model, {}));
  const std::map<std::string, Rigid3d> one = {*adjusted.true_poses.begin()};
  CHECK_FALSE(FitObservationsToPoses(adjusted.model, one));
  std::map<std::string, Rigid3d> two = one;
  two.insert(*std::next(adjusted.true_poses.begin()));
  const std::optional<PoseFit> fit = FitObservationsToPoses(adjusted.model, two);
  REQUIRE(fit);
  CHECK(fit->num_observations < int(adjusted.model.NumObservations()));
}

}  // namespace
}  // namespace flysfm
