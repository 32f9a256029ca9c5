#include "core/sub_models.h"

#include <algorithm>
#include <random>
#include <set>
#include <unordered_map>

#include <catch2/catch.hpp>

#include "tests/testing/scene_reconstruction.h"
#include "tests/testing/synthetic.h"

namespace flysfm {
namespace {

using testing::SceneImageId;

const Sim3d kSecondFromWorld(
    0.4, Eigen::Quaterniond(Eigen::AngleAxisd(-1.1, Eigen::Vector3d(2, -1, 1).normalized())),
    Eigen::Vector3d(-3, 7, 2));

// A scene broken after `num_first` of its ten images, and the linking shot's
// 2D-3D correspondences into the second sub-model: its keypoints whose scene
// point the second sub-model holds too.
struct BrokenChain {
  testing::SyntheticScene scene;
  testing::TwoSubModelScene two;
  image_t linking_image = kInvalidImageId;
  std::vector<Correspondence2D3D> correspondences;

  BrokenChain(int num_first, int linking, double noise_px = 0.5) {
    testing::SyntheticSceneOptions options;
    options.num_images = 10;
    options.num_points = 500;
    options.noise_px = noise_px;
    options.arc_deg = 90;
    scene = testing::MakeSyntheticScene(options);
    two = testing::TwoSubModelsFromScene(scene, num_first, kSecondFromWorld);
    linking_image = SceneImageId(linking);
    const Image& image = two.reconstruction.image(linking_image);
    const std::vector<point3D_t>& own_ids = linking < num_first ? two.first_ids : two.second_ids;
    const std::vector<point3D_t>& other_ids = linking < num_first ? two.second_ids : two.first_ids;
    std::unordered_map<point3D_t, std::size_t> scene_point;
    for (std::size_t p = 0; p < own_ids.size(); ++p) scene_point[own_ids[p]] = p;
    for (point2D_t idx = 0; idx < image.points2D.size(); ++idx) {
      const point3D_t own = image.points2D[idx].point3D_id;
      if (own == kInvalidPoint3DId) continue;
      const point3D_t other = other_ids[scene_point.at(own)];
      if (other != kInvalidPoint3DId) {
        correspondences.push_back({idx, image.points2D[idx].xy, other});
      }
    }
  }

  Reconstruction& reconstruction() { return two.reconstruction; }
};

// The linking shot's pose in the second sub-model, and the link it makes.
std::optional<SubModelLink> Link(BrokenChain& chain, std::string* why_not = nullptr,
                                 const SubModelOptions& options = SubModelOptions()) {
  const std::optional<SubModelView> view =
      PoseInSubModel(chain.reconstruction(), chain.linking_image, chain.two.second_id,
                     chain.correspondences, options, why_not);
  if (!view) return std::nullopt;
  return FindSubModelLink(chain.reconstruction(), {*view}, options, why_not);
}

void CheckSimilarity(const Sim3d& estimate, const Sim3d& truth, double tolerance) {
  CHECK(std::abs(estimate.scale / truth.scale - 1) < tolerance);
  CHECK(estimate.rotation.angularDistance(truth.rotation) < tolerance);
  CHECK((estimate.translation - truth.translation).norm() <
        tolerance * (1 + truth.translation.norm()));
}

TEST_CASE("A shot of one sub-model that sees the other's points links them") {
  BrokenChain chain(6, 5);
  REQUIRE(chain.correspondences.size() > 100);
  std::string why_not;
  const std::optional<SubModelLink> link =
      Link(chain, &why_not);
  INFO(why_not);
  REQUIRE(link);
  CHECK(link->own_id == Reconstruction::kFirstModelId);
  CHECK(link->other_id == chain.two.second_id);
  // Both sub-models hold their points exactly (the first at the truth): the
  // 3D-3D fit is exact, whatever the keypoints' noise did to the pose.
  CheckSimilarity(link->own_from_other, Inverse(kSecondFromWorld), 1e-9);
  CHECK(int(link->same_points.size()) == int(chain.correspondences.size()));
}

TEST_CASE("A merge fuses the points that are one and keeps every observation") {
  BrokenChain chain(6, 5);
  Reconstruction& r = chain.reconstruction();
  const std::optional<SubModelLink> link =
      Link(chain);
  REQUIRE(link);
  const std::size_t num_observations = r.NumObservations();
  const std::size_t num_points = r.NumPoints3D();
  const SubModelMerge merge = MergeSubModels(*link, &r);
  CHECK(merge.model_id == Reconstruction::kFirstModelId);  // six images against four
  REQUIRE(r.Models().size() == 1);
  CHECK(r.NumObservations() == num_observations);
  CHECK(r.NumPoints3D() == num_points - link->same_points.size());
  std::set<point3D_t> fused(merge.fused_points.begin(), merge.fused_points.end());
  CHECK(fused.size() == link->same_points.size());
  for (const auto& [own, other] : link->same_points) {
    CHECK(fused.count(own) == 1);  // the larger sub-model's id survives
    CHECK_FALSE(r.ExistsPoint3D(other));
  }
  // Every pose and point at the truth again.
  for (int i = 0; i < 10; ++i) {
    const Image& image = r.image(SceneImageId(i));
    CHECK(image.model_id == Reconstruction::kFirstModelId);
    CHECK((ProjectionCenter(*image.cam_from_world) -
           ProjectionCenter(chain.scene.cams_from_world[i]))
              .norm() < 1e-9);
  }
  for (std::size_t p = 0; p < chain.scene.points.size(); ++p) {
    for (const point3D_t id : {chain.two.first_ids[p], chain.two.second_ids[p]}) {
      if (r.ExistsPoint3D(id)) CHECK((r.point3D(id).xyz - chain.scene.points[p]).norm() < 1e-9);
    }
  }
}

TEST_CASE("The smaller sub-model goes into the larger's frame") {
  // The linking shot lies in the smaller: its sub-model moves.
  BrokenChain chain(3, 2);
  Reconstruction& r = chain.reconstruction();
  const std::optional<SubModelLink> link =
      Link(chain);
  REQUIRE(link);
  const SubModelMerge merge = MergeSubModels(*link, &r);
  CHECK(merge.model_id == chain.two.second_id);
  for (int i = 0; i < 10; ++i) {
    const Image& image = r.image(SceneImageId(i));
    CHECK(image.model_id == chain.two.second_id);
    CHECK((ProjectionCenter(*image.cam_from_world) -
           kSecondFromWorld * ProjectionCenter(chain.scene.cams_from_world[i]))
              .norm() < 1e-9);
  }
  for (const point3D_t id : merge.fused_points) {
    CHECK(r.ModelOfPoint(id) == chain.two.second_id);
  }
}

TEST_CASE("Wrong correspondences are outvoted and left unfused") {
  BrokenChain chain(6, 5);
  // 40 % of the correspondences lead to another point of the second
  // sub-model, as matches on a repeated texture would: their points are
  // passed round among them.
  std::vector<std::size_t> chosen;
  for (std::size_t i = 0; i < chain.correspondences.size(); ++i) {
    if (i % 5 < 2) chosen.push_back(i);
  }
  std::set<std::pair<point2D_t, point3D_t>> wrong;
  const point3D_t first_point = chain.correspondences[chosen.front()].point3D_id;
  for (std::size_t k = 0; k < chosen.size(); ++k) {
    Correspondence2D3D& c = chain.correspondences[chosen[k]];
    c.point3D_id = k + 1 < chosen.size() ? chain.correspondences[chosen[k + 1]].point3D_id
                                         : first_point;
    wrong.insert({c.point2D_idx, c.point3D_id});
  }
  REQUIRE(wrong.size() > 40);
  const std::optional<SubModelLink> link =
      Link(chain);
  REQUIRE(link);
  CheckSimilarity(link->own_from_other, Inverse(kSecondFromWorld), 1e-9);
  CHECK(link->same_points.size() == chain.correspondences.size() - wrong.size());
  const Image& image = chain.reconstruction().image(chain.linking_image);
  for (const auto& [own, other] : link->same_points) {
    for (const auto& [idx, wrong_other] : wrong) {
      CHECK_FALSE((other == wrong_other && image.points2D[idx].point3D_id == own));
    }
  }
}

TEST_CASE("Sub-models that disagree in shape, or too little evidence, are not linked") {
  SECTION("the other sub-model's depths are squeezed along the linking shot's view") {
    // What a wrong link through a similar-looking structure at another depth
    // gives: the shot's pose may be found, but its points do not agree.
    BrokenChain chain(6, 5);
    Reconstruction& r = chain.reconstruction();
    const Rigid3d cam_from_world = chain.scene.cams_from_world[5];
    for (std::size_t p = 0; p < chain.scene.points.size(); ++p) {
      const point3D_t id = chain.two.second_ids[p];
      if (id == kInvalidPoint3DId) continue;
      Eigen::Vector3d in_cam = cam_from_world * chain.scene.points[p];
      in_cam *= 0.6 + 0.8 * double(p % 17) / 16;  // from 0.6 to 1.4 times as far
      r.point3D(id).xyz = kSecondFromWorld * (Inverse(cam_from_world) * in_cam);
    }
    std::string why_not;
    CHECK_FALSE(Link(chain, &why_not));
    CHECK_FALSE(why_not.empty());
  }
  SECTION("fewer correspondences than a link needs") {
    BrokenChain chain(6, 5);
    chain.correspondences.resize(SubModelOptions().min_link_points - 1);
    std::string why_not;
    CHECK_FALSE(Link(chain, &why_not));
    CHECK(why_not == std::to_string(SubModelOptions().min_link_points - 1) + " correspondences");
  }
  SECTION("correspondences that are all wrong") {
    BrokenChain chain(6, 5);
    std::vector<point3D_t> ids;
    for (const Correspondence2D3D& c : chain.correspondences) ids.push_back(c.point3D_id);
    std::mt19937 rng(4);
    std::shuffle(ids.begin(), ids.end(), rng);
    for (std::size_t i = 0; i < ids.size(); ++i) chain.correspondences[i].point3D_id = ids[i];
    CHECK_FALSE(Link(chain));
  }
}

TEST_CASE("A shot matching only a repeated structure's twin, not what is around it, links nothing") {
  // The second sub-model holds a twin of the structure the shot sees where
  // it is registered, the points on one side of the scene (x < -1/2 of its
  // half-size): the shot's correspondences reach the twin's points only, as
  // a facade's twin elsewhere gives them, and none of the twin's
  // surroundings that the second sub-model's images show around it from
  // where the shot stands. The twin's points agree and reproject under the
  // similarity that maps one onto the other.
  BrokenChain chain(6, 5);
  std::unordered_map<point3D_t, std::size_t> scene_point;
  for (std::size_t p = 0; p < chain.two.second_ids.size(); ++p) {
    scene_point[chain.two.second_ids[p]] = p;
  }
  std::vector<Correspondence2D3D>& correspondences = chain.correspondences;
  correspondences.erase(
      std::remove_if(correspondences.begin(), correspondences.end(),
                     [&](const Correspondence2D3D& c) {
                       return chain.scene.points[scene_point.at(c.point3D_id)].x() >= -0.5;
                     }),
      correspondences.end());
  REQUIRE(int(correspondences.size()) > 2 * SubModelOptions().min_link_points);

  // Every geometric test passes: geometry alone would merge.
  SubModelOptions blind;
  blind.min_context_ratio = 0;
  std::string why_not;
  const std::optional<SubModelLink> geometric = Link(chain, &why_not, blind);
  INFO(why_not);
  REQUIRE(geometric);
  // The shot sees its own sub-model's points wherever it looks (it observes
  // each visible point), the twin's only in a quarter of the view.
  CHECK(geometric->registered_context_share > 0.9);
  CHECK(geometric->posed_context_share < 0.35);

  CHECK_FALSE(Link(chain, &why_not));
  CHECK(why_not.rfind("context unmatched", 0) == 0);

  // Matched in full, the same sub-models link.
  BrokenChain whole(6, 5);
  const std::optional<SubModelLink> link = Link(whole, &why_not);
  REQUIRE(link);
  CHECK(link->posed_context_share > 0.9);
  CHECK(link->registered_context_share > 0.9);
}

TEST_CASE("Two shots posed in both link sub-models whose points they do not share") {
  // Shot 5 (the first sub-model) sees the second's points with other
  // keypoints than its own points, and so does shot 6 the other way round:
  // no 3D-3D correspondence, as when each sub-model holds one wall.
  BrokenChain chain(6, 5);
  Reconstruction& r = chain.reconstruction();
  const image_t shot5 = chain.linking_image;
  const image_t shot6 = SceneImageId(6);
  std::vector<Correspondence2D3D> into_second;
  for (std::size_t k = 0; k < chain.correspondences.size(); ++k) {
    const Correspondence2D3D& c = chain.correspondences[k];
    if (k % 2 == 0) continue;
    if (r.image(shot5).points2D[c.point2D_idx].HasPoint3D()) {
      r.DeleteObservation(shot5, c.point2D_idx);
    }
    into_second.push_back(c);
  }
  std::unordered_map<point3D_t, std::size_t> scene_point;
  for (std::size_t p = 0; p < chain.two.second_ids.size(); ++p) {
    scene_point[chain.two.second_ids[p]] = p;
  }
  std::vector<Correspondence2D3D> into_first;
  int k = 0;
  for (point2D_t idx = 0; idx < r.image(shot6).points2D.size(); ++idx) {
    const point3D_t own = r.image(shot6).points2D[idx].point3D_id;
    if (own == kInvalidPoint3DId) continue;
    const point3D_t other = chain.two.first_ids[scene_point.at(own)];
    if (other == kInvalidPoint3DId || k++ % 2 == 0) continue;
    r.DeleteObservation(shot6, idx);
    into_first.push_back({idx, r.image(shot6).points2D[idx].xy, other});
  }
  // Deleted observations may have taken a point with them.
  for (auto* list : {&into_second, &into_first}) {
    list->erase(std::remove_if(list->begin(), list->end(),
                               [&](const Correspondence2D3D& c) {
                                 return !r.ExistsPoint3D(c.point3D_id);
                               }),
                list->end());
  }
  const std::optional<SubModelView> view5 =
      PoseInSubModel(r, shot5, chain.two.second_id, into_second, SubModelOptions());
  const std::optional<SubModelView> view6 =
      PoseInSubModel(r, shot6, Reconstruction::kFirstModelId, into_first, SubModelOptions());
  REQUIRE(view5);
  REQUIRE(view6);

  std::string why_not;
  CHECK_FALSE(FindSubModelLink(r, {*view5}, SubModelOptions(), &why_not));
  CHECK(why_not == "0 points seen in both and one shot");
  const std::optional<SubModelLink> link =
      FindSubModelLink(r, {*view5, *view6}, SubModelOptions(), &why_not);
  INFO(why_not);
  REQUIRE(link);
  CHECK_FALSE(link->from_points);
  CHECK(link->num_shots == 2);
  CHECK(link->same_points.empty());
  // The poses from 0.5 px keypoints put each centre within millimetres at
  // 5 m; the two shots are 0.87 m apart, so the scale holds to a per cent.
  CheckSimilarity(link->own_from_other, Inverse(kSecondFromWorld), 0.02);
}

TEST_CASE("Sub-model options are checked") {
  CHECK(SubModelOptions().Check());
  SubModelOptions options;
  options.min_link_points = 2;
  CHECK_FALSE(options.Check());
  options = SubModelOptions();
  options.min_inlier_ratio = 1.5;
  CHECK_FALSE(options.Check());
  options = SubModelOptions();
  options.max_relative_distance = 0;
  CHECK_FALSE(options.Check());
  options = SubModelOptions();
  options.min_context_ratio = 1.1;
  CHECK_FALSE(options.Check());
  options = SubModelOptions();
  options.context_max_angle_deg = 0;
  CHECK_FALSE(options.Check());
  options = SubModelOptions();
  options.context_max_distance_ratio = 0.9;
  CHECK_FALSE(options.Check());
}

}  // namespace
}  // namespace flysfm
