#include "core/pair_verification.h"

#include <catch2/catch.hpp>

#include <algorithm>

#include "core/engine.h"
#include "io/synthetic/synthetic_source.h"
#include "tests/testing/warped_pair.h"
#include "tests/testing/rendered_capture.h"

namespace flysfm {
namespace {

struct RenderedPair {
  Reconstruction reconstruction;
  LsmImageStore lsm_images{LsmImageStore::Options{}};
  std::vector<FeatureSet> features;
};

// Two neighbouring views of the rendered capture, as the engine holds them.
void AddViews(RenderedPair* pair) {
  SyntheticCaptureOptions options;
  options.num_views = 2;
  options.path_length = 0.4;
  const SyntheticCapture capture = testing::RenderedCapture(options);
  const camera_t camera_id = pair->reconstruction.AddCamera(capture.camera);
  for (const Frame& frame : capture.frames) {
    PreparedFrame prepared = Engine::Prepare(frame, Engine::Options());
    REQUIRE(prepared.error.empty());
    std::vector<Eigen::Vector2d> keypoints;
    for (const Keypoint& k : prepared.features.keypoints) keypoints.emplace_back(k.x, k.y);
    const image_t id = pair->reconstruction.AddImage(frame.name, camera_id, keypoints);
    pair->lsm_images.Add(id, prepared.grey);
    pair->features.push_back(std::move(prepared.features));
  }
}

TEST_CASE("A rendered pair verifies, and LSM refines each keypoint once") {
  RenderedPair pair;
  AddViews(&pair);
  PairVerifier verifier(PairVerifier::Options(), &pair.reconstruction, &pair.lsm_images);
  std::vector<char> refined(pair.features[1].size(), 0);
  StageTimes times;
  const PairVerification verification = verifier.Verify(
      2, pair.features[1], RootSift(pair.features[1].descriptors), 1, pair.features[0], refined,
      &times);
  REQUIRE(verification.verified());
  // The rendered scene is mostly one wall: E or H, with a pose either way.
  CHECK(verification.geometry.has_pose);
  CHECK(int(verification.matches.size()) >= PairVerifier::Options().two_view.min_num_inliers_f);
  // Nearly every kept match was refined by LSM, each within the reach of
  // its 15x15 window.
  CHECK(verification.refined.size() >= 0.9 * verification.matches.size());
  for (const auto& [idx, xy] : verification.refined) {
    CHECK((xy - pair.reconstruction.image(2).points2D[idx].xy).norm() < 7.5);
  }
  CHECK(times.matching > 0);
  CHECK(times.verification > 0);
  CHECK(times.lsm > 0);

  // Keypoints refined by an earlier pair keep their position.
  for (const auto& [idx, xy] : verification.refined) refined[idx] = 1;
  const PairVerification again = verifier.Verify(
      2, pair.features[1], RootSift(pair.features[1].descriptors), 1, pair.features[0], refined,
      &times);
  CHECK(again.refined.empty());
  CHECK(again.matches.size() >= verification.matches.size());

  // The ablation: no LSM, the geometry's inliers as they are.
  PairVerifier::Options raw;
  raw.lsm_refinement = false;
  const PairVerification plain = PairVerifier(raw, &pair.reconstruction, &pair.lsm_images)
                                     .Verify(2, pair.features[1],
                                             RootSift(pair.features[1].descriptors), 1,
                                             pair.features[0], refined, &times);
  CHECK(plain.refined.empty());
  CHECK(plain.num_lsm_rejected == 0);
  CHECK(int(plain.matches.size()) == plain.geometry.num_inliers);
}

// A photographer steps twice as near and turns the camera: the new image
// shows the other's texture magnified 2x and rotated. LSM keeps the matches
// and refines them to the truth of the warp, well below SIFT's error.
TEST_CASE("Matches of a view from twice as near, turned, are refined on their scale") {
  const double angle_deg = GENERATE(0.0, 35.0, 90.0);
  const testing::WarpedPair warped =
      testing::MakeWarpedPair(800, 600, angle_deg, 2.0, 800, 600, 11);
  Reconstruction reconstruction;
  const camera_t camera_id =
      reconstruction.AddCamera(Camera::FromString("PINHOLE 700,700,399.5,299.5", 800, 600));
  LsmImageStore lsm_images{LsmImageStore::Options{}};
  std::vector<FeatureSet> features;
  for (const cv::Mat& grey : {warped.image1, warped.image2}) {
    features.push_back(ExtractFeatures(grey, SiftOptions()));
    std::vector<Eigen::Vector2d> keypoints;
    for (const Keypoint& k : features.back().keypoints) keypoints.emplace_back(k.x, k.y);
    const image_t id = reconstruction.AddImage("view" + std::to_string(features.size()),
                                               camera_id, keypoints);
    lsm_images.Add(id, grey);
  }
  PairVerifier verifier(PairVerifier::Options(), &reconstruction, &lsm_images);
  StageTimes times;
  const PairVerification pair =
      verifier.Verify(2, features[1], RootSift(features[1].descriptors), 1, features[0],
                      std::vector<char>(features[1].size(), 0), &times);
  REQUIRE(pair.verified());
  INFO("angle " << angle_deg << ": " << pair.geometry.num_inliers << " inliers, "
                << pair.matches.size() << " kept, " << pair.refined.size() << " refined");
  CHECK(pair.refined.size() == pair.matches.size());
  CHECK(pair.matches.size() >= 0.8 * pair.geometry.num_inliers);
  // The truth: where the other image's keypoint lands under the warp.
  std::vector<double> errors;
  for (std::size_t i = 0; i < pair.matches.size(); ++i) {
    const Eigen::Vector2d other_xy = reconstruction.image(1).points2D[pair.matches[i].idx2].xy;
    const Eigen::Vector2d truth = testing::ApplyHomography(warped.homography, other_xy);
    const auto refined = std::find_if(pair.refined.begin(), pair.refined.end(), [&](const auto& r) {
      return r.first == point2D_t(pair.matches[i].idx1);
    });
    REQUIRE(refined != pair.refined.end());
    errors.push_back((refined->second - truth).norm());
  }
  std::sort(errors.begin(), errors.end());
  INFO("error median " << errors[errors.size() / 2] << " px, 95 % "
                       << errors[errors.size() * 95 / 100] << " px");
  CHECK(errors[errors.size() / 2] < 0.05);
  CHECK(errors[errors.size() * 95 / 100] < 0.2);
}

}  // namespace
}  // namespace flysfm
