#include "core/pair_verification.h"

#include <catch2/catch.hpp>

#include "core/engine.h"
#include "io/synthetic/synthetic_source.h"

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
  const SyntheticCapture capture = MakeSyntheticCapture(options);
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
      2, pair.features[1].descriptors, 1, pair.features[0].descriptors, refined, &times);
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
      2, pair.features[1].descriptors, 1, pair.features[0].descriptors, refined, &times);
  CHECK(again.refined.empty());
  CHECK(again.matches.size() >= verification.matches.size());

  // The ablation: no LSM, the geometry's inliers as they are.
  PairVerifier::Options raw;
  raw.lsm_refinement = false;
  const PairVerification plain = PairVerifier(raw, &pair.reconstruction, &pair.lsm_images)
                                     .Verify(2, pair.features[1].descriptors, 1,
                                             pair.features[0].descriptors, refined, &times);
  CHECK(plain.refined.empty());
  CHECK(plain.num_lsm_rejected == 0);
  CHECK(int(plain.matches.size()) == plain.geometry.num_inliers);
}

}  // namespace
}  // namespace flysfm
