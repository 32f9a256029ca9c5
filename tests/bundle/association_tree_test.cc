#include "bundle/association_tree.h"

#include <cmath>
#include <limits>
#include <map>
#include <random>
#include <vector>

#include <catch2/catch.hpp>

#include "bundle/bundle_adjuster.h"
#include "tests/bundle/synthetic_problem.h"
#include "tests/testing/ground_path.h"

namespace flysfm {
namespace {

using Tree = HierarchicalAssociationTree;

TEST_CASE("Each image joins the ripple where it first appears") {
  // 0 is new; its ranked neighbours are 1, 2, 3; theirs overlap.
  const std::map<int, std::vector<int>> graph = {
      {0, {1, 2, 3}}, {1, {2, 4, 0, 9}}, {2, {5, 1}}, {3, {4, 6}},
      {4, {7}},       {5, {8}},          {6, {}},     {7, {}}, {8, {}}};
  const Tree::NeighbourFunction neighbours = [&](int id) { return graph.at(id); };
  Tree::Options options;
  options.top_n = 2;
  options.depth = 3;
  const Tree tree = Tree::Build(0, neighbours, options);

  REQUIRE(tree.ripples().size() == 4);
  CHECK(tree.ripples()[0] == std::vector<int>{0});
  // Only the top two of each list: 3 and 9 are cut off.
  CHECK(tree.ripples()[1] == std::vector<int>{1, 2});
  CHECK(tree.ripples()[2] == std::vector<int>{4, 5});
  CHECK(tree.ripples()[3] == std::vector<int>{7, 8});
  CHECK(tree.NewImage() == 0);
  CHECK(tree.NumImages() == 7);
  CHECK(tree.RippleOf(2) == 1);
  CHECK(tree.RippleOf(3) == -1);
  CHECK(tree.RippleOf(9) == -1);

  SECTION("and the tree stops when the neighbours run out") {
    options.depth = 6;
    CHECK(Tree::Build(0, neighbours, options).ripples().size() == 4);
  }
}

TEST_CASE("Ripple weights follow Eq. 4") {
  Tree::Options options;
  options.depth = 4;
  CHECK(options.Weight(0) == 1.0);
  CHECK(options.Weight(1) == 1.0);
  CHECK(options.Weight(2) == 2.0);
  CHECK(options.Weight(3) == 4.0);
  CHECK(std::isinf(options.Weight(4)));
  options.k = 1.0;
  options.fix_outermost_ripple = false;
  for (int ripple = 0; ripple <= options.depth; ++ripple) {
    CHECK(options.Weight(ripple) == 1.0);
  }
  CHECK(options.Check());
  options.k = 0.5;
  CHECK_FALSE(options.Check());
  options.k = 2;
  options.top_n = 0;
  CHECK_FALSE(options.Check());
}

// A block of three strips; the new image is the last one, its pose perturbed
// as a registration from few correspondences would leave it.
struct LocalScene {
  testing::SyntheticScene scene;
  BundleProblem problem;
  std::vector<std::vector<int>> ranked;
};

LocalScene MakeLocalScene() {
  testing::GroundPathSceneOptions options;
  options.num_images = 120;
  options.images_per_strip = 40;
  options.noise_px = 0.5;
  options.seed = 11;
  LocalScene local;
  local.scene = testing::MakeGroundPathScene(options);
  local.problem = testing::BundleProblemFromScene(local.scene);
  local.ranked = testing::RankByCovisibility(local.scene, 8);
  std::mt19937 rng(12);
  testing::PerturbPose(rng, 1.0, 0.3, &local.problem.images.back().cam_from_world);
  return local;
}

Tree BuildTree(const LocalScene& local, const Tree::Options& options) {
  const int new_image = static_cast<int>(local.problem.images.size()) - 1;
  return Tree::Build(
      new_image, [&](int id) { return local.ranked[id]; }, options);
}

// Mean displacement of the camera centres of each ripple, and the largest
// rotation change in it.
struct RippleChange {
  std::vector<double> mean_shift;
  std::vector<double> max_rotation_deg;
};

RippleChange ChangePerRipple(const Tree& tree, const BundleProblem& before,
                             const BundleProblem& after) {
  RippleChange change;
  for (const std::vector<int>& ripple : tree.ripples()) {
    double shift = 0;
    double rotation = 0;
    for (const int id : ripple) {
      const Rigid3d& a = before.images[id].cam_from_world;
      const Rigid3d& b = after.images[id].cam_from_world;
      shift += (ProjectionCenter(a) - ProjectionCenter(b)).norm() / ripple.size();
      rotation = std::max(rotation, RotationDifferenceDeg(a, b));
    }
    change.mean_shift.push_back(shift);
    change.max_rotation_deg.push_back(rotation);
  }
  return change;
}

BundleProblem SolveLocal(const BundleProblem& source, const Tree& tree,
                         BundleAdjuster::Summary* summary) {
  LocalBundle local = ExtractLocalBundle(source, tree);
  *summary = BundleAdjuster({}).Solve(&local.problem);
  BundleProblem solved = source;
  WriteBack(local, &solved);
  return solved;
}

TEST_CASE("The weighted local BA moves farther ripples less and the last not") {
  const LocalScene local = MakeLocalScene();
  const Tree tree = BuildTree(local, {});
  REQUIRE(tree.ripples().size() == 4);

  BundleAdjuster::Summary summary;
  const BundleProblem solved = SolveLocal(local.problem, tree, &summary);
  INFO(summary.BriefReport());
  REQUIRE(summary.termination == BundleAdjuster::Termination::kConvergence);
  CHECK(summary.num_pose_priors == static_cast<int>(tree.ripples()[2].size()));

  const RippleChange change = ChangePerRipple(tree, local.problem, solved);
  INFO("shift per ripple " << change.mean_shift[0] << " " << change.mean_shift[1]
                           << " " << change.mean_shift[2] << " "
                           << change.mean_shift[3]);
  CHECK(change.mean_shift[2] < change.mean_shift[1]);
  CHECK(change.mean_shift[3] == 0.0);
  CHECK(change.max_rotation_deg[3] == 0.0);
  // Images outside the tree only lend their observations.
  for (size_t i = 0; i < solved.images.size(); ++i) {
    if (tree.RippleOf(static_cast<int>(i)) >= 0) continue;
    CHECK(solved.images[i].cam_from_world.translation ==
          local.problem.images[i].cam_from_world.translation);
  }
  // The new image's 1 degree / 0.3 perturbation is undone to a tenth of it.
  // The noise-level error is about 0.01 and 0.05 degree here (0.5 px on 300
  // points at f = 500; a nadir view of nearly flat ground trades tilt for
  // shift at 10 units per radian), an unconverged solve leaves far more.
  const Rigid3d& estimate = solved.images.back().cam_from_world;
  const Rigid3d& truth = local.scene.cams_from_world.back();
  CHECK((ProjectionCenter(estimate) - ProjectionCenter(truth)).norm() < 0.03);
  CHECK(RotationDifferenceDeg(estimate, truth) < 0.1);

  SECTION("and ripple 2 moves less than without its weight") {
    Tree::Options plain;
    plain.k = 1;
    plain.fix_outermost_ripple = false;
    BundleAdjuster::Summary plain_summary;
    const BundleProblem unweighted =
        SolveLocal(local.problem, BuildTree(local, plain), &plain_summary);
    const RippleChange plain_change =
        ChangePerRipple(tree, local.problem, unweighted);
    CHECK(change.mean_shift[2] < plain_change.mean_shift[2]);
  }
}

TEST_CASE("With k = 1 and no fixed ripple the weighted BA is the plain local BA") {
  const LocalScene local = MakeLocalScene();
  Tree::Options options;
  options.k = 1;
  options.fix_outermost_ripple = false;
  const Tree tree = BuildTree(local, options);

  // The plain local BA, assembled here independently: the tree's images free,
  // the points they see, the other observers of those points constant.
  BundleProblem plain = local.problem;
  std::vector<char> in_block(plain.points.size(), 0);
  for (const BundleObservation& obs : plain.observations) {
    if (tree.RippleOf(obs.image) >= 0) in_block[obs.point] = 1;
  }
  std::vector<BundleObservation> kept;
  for (const BundleObservation& obs : plain.observations) {
    if (in_block[obs.point]) kept.push_back(obs);
  }
  plain.observations = kept;
  for (size_t i = 0; i < plain.images.size(); ++i) {
    plain.images[i].constant_pose = tree.RippleOf(static_cast<int>(i)) < 0;
  }
  const BundleAdjuster::Summary plain_summary = BundleAdjuster({}).Solve(&plain);
  REQUIRE(plain_summary.IsSolutionUsable());

  BundleAdjuster::Summary summary;
  const BundleProblem weighted = SolveLocal(local.problem, tree, &summary);
  REQUIRE(summary.IsSolutionUsable());
  CHECK(summary.num_pose_priors == 0);
  CHECK(summary.num_free_images == plain_summary.num_free_images);
  CHECK(summary.num_residuals == plain_summary.num_residuals);
  CHECK(summary.final_cost == Approx(plain_summary.final_cost).epsilon(1e-9));
  // The same problem in another order: equal up to round-off.
  for (size_t i = 0; i < plain.images.size(); ++i) {
    const Rigid3d& a = plain.images[i].cam_from_world;
    const Rigid3d& b = weighted.images[i].cam_from_world;
    CHECK(a.rotation.angularDistance(b.rotation) < 1e-9);
    CHECK((a.translation - b.translation).norm() < 1e-9);
  }
  for (size_t p = 0; p < plain.points.size(); ++p) {
    if (in_block[p]) CHECK((plain.points[p] - weighted.points[p]).norm() < 1e-8);
  }
}

TEST_CASE("A local bundle keeps every observation of its points") {
  const LocalScene local = MakeLocalScene();
  const Tree tree = BuildTree(local, {});
  const LocalBundle bundle = ExtractLocalBundle(local.problem, tree);
  REQUIRE(bundle.problem.Check());

  std::vector<int> track_length(local.problem.points.size(), 0);
  for (const BundleObservation& obs : local.problem.observations) {
    ++track_length[obs.point];
  }
  std::vector<int> local_length(bundle.problem.points.size(), 0);
  for (const BundleObservation& obs : bundle.problem.observations) {
    ++local_length[obs.point];
  }
  for (size_t p = 0; p < bundle.source_point.size(); ++p) {
    CHECK(local_length[p] == track_length[bundle.source_point[p]]);
  }
  for (size_t i = 0; i < bundle.problem.images.size(); ++i) {
    const int source = bundle.source_image[i];
    const int ripple = tree.RippleOf(source);
    const bool refined = ripple >= 0 && ripple < 3;
    CHECK(bundle.problem.images[i].constant_pose == !refined);
    if (refined) CHECK(bundle.problem.images[i].weight == tree.WeightOf(source));
  }
}

}  // namespace
}  // namespace flysfm
