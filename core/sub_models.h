#pragma once

// Sub-models (Reconstruction::Models) linked by a shot and merged into one:
// the evidence that two are one scene, the similarity between their frames,
// and the merge of the smaller into the larger with the points that are one
// fused. docs/engine.md, "Sub-models", says why each test is there.

#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "core/registration.h"
#include "core/scene/reconstruction.h"
#include "geometry/absolute_pose.h"
#include "geometry/sim3d.h"

namespace flysfm {

struct SubModelOptions {
  // Off: one model; a shot that does not fit it waits (Engine).
  bool enabled = true;
  // A link needs the linking shot's pose in the other sub-model from at
  // least this many of its points (RANSAC inliers), and at least this many
  // of them to be points the shot observes in its own, agreeing under one
  // similarity: this many over a shot's field of view fix the similarity's
  // seven degrees of freedom with redundancy to spare, where registration's
  // 20 correspondences only start a pose.
  int min_link_points = 30;
  // ... and at least this share of those 3D-3D correspondences to agree: a
  // repeated structure matched by mistake agrees in part at best.
  double min_inlier_ratio = 0.5;
  // Agreement: a mapped point within this share of the median depth (seen
  // from the linking shot) of its counterpart, and the linking shot's two
  // poses within it (centres; rotations in radians). Depth is what a
  // sub-model knows least well (a narrow baseline's points spread along
  // their rays); the reprojection test below checks the rest.
  double max_relative_distance = 0.05;
  // ... and, of the agreeing points, at least this share reprojecting within
  // `max_reprojection_error_px` into every image that observes the
  // counterpart: those images see the mapped point from other directions,
  // where a wrong depth or scale shows.
  double min_reprojected_ratio = 0.8;
  double max_reprojection_error_px = 4.0;
  // Past Engine::Options::max_verified_pairs, a shot is still verified
  // against up to this many of the best-ranked retrieval candidates of each
  // sub-model it has no verified pair in: a walk's own recent shots rank
  // first and fill the limit, which would hide the pairs that link its
  // sub-model to another until the walks overlap by that many shots.
  int link_candidates = 2;
  // Context: each shot's pose in a sub-model says which of its points the
  // shot should see: those its verified neighbours there, taken from about
  // where the pose puts it, show in its view from within
  // `context_max_angle_deg` of its ray and at a distance within
  // `context_max_distance_ratio` of its own (where SIFT finds a keypoint
  // again); and what share of those it matched. A true link sees one place
  // under both poses: the two shares are alike. A repeated structure (the
  // same facade twice, a symmetric object) is matched only where it
  // repeats, and its surroundings, which the wrong pose predicts too, not:
  // the lower share must reach `min_context_ratio` of the higher. 0.4
  // lies between the lowest true link of bench_agents (0.51: a ring closed
  // across its gap, its two sets of neighbours unlike) and a twin facade
  // filling a third of the view (0.32, tests/core/twin_facades_test.cc).
  double min_context_ratio = 0.4;
  double context_max_angle_deg = 20.0;
  double context_max_distance_ratio = 1.5;
  // The linking shot's pose in the other sub-model.
  AbsolutePoseOptions absolute_pose;

  bool Check() const;
};

// A shot registered in one sub-model and posed in another by its 2D-3D
// correspondences into it: what links two sub-models.
struct SubModelView {
  image_t image_id = kInvalidImageId;
  model_t registered_in = kInvalidModelId;
  model_t posed_in = kInvalidModelId;
  Rigid3d cam_from_posed;
  // The correspondences the pose keeps (RANSAC inliers).
  std::vector<Correspondence2D3D> inliers;
  // The points of `registered_in` the shot reaches the same way (its
  // verified neighbours' tracks) that agree with its pose there
  // (RegisteredMatches): what the context test weighs the inliers against.
  // Empty: the points the shot observes there.
  std::vector<point3D_t> registered_matches;
  // The shot's verified neighbours in each sub-model: the images whose
  // points the context test expects it to match. Empty: the images that
  // observe the points it matched there.
  std::vector<image_t> registered_neighbours;
  std::vector<image_t> posed_neighbours;
};

// Of the registered `image_id`'s `correspondences` into its own sub-model
// (Find2D3DCorrespondences), the points reprojecting within the pose's
// inlier threshold: counted as the inliers into the other are.
std::vector<point3D_t> RegisteredMatches(const Reconstruction& reconstruction,
                                         image_t image_id,
                                         const std::vector<Correspondence2D3D>& correspondences,
                                         const SubModelOptions& options);

// The registered `image_id`'s pose in sub-model `other_id` from
// `correspondences` (Find2D3DCorrespondences); nothing with fewer than
// min_link_points inliers (`why_not` then says so).
std::optional<SubModelView> PoseInSubModel(
    const Reconstruction& reconstruction, image_t image_id, model_t other_id,
    const std::vector<Correspondence2D3D>& correspondences, const SubModelOptions& options,
    std::string* why_not = nullptr);

struct SubModelLink {
  model_t own_id = kInvalidModelId;    // views.front().registered_in
  model_t other_id = kInvalidModelId;
  Sim3d own_from_other;
  // Points that are one: (in own_id, in other_id), each agreeing and
  // reprojecting.
  std::vector<std::pair<point3D_t, point3D_t>> same_points;
  // How the similarity was found: from the points the shots see in both
  // (3D-3D), else from two shots or more posed in both.
  bool from_points = false;
  int num_agreeing = 0;  // 3D-3D correspondences under own_from_other
  int num_shots = 0;
  // The context test's shares, over the shots: of the points each shot's
  // pose says it should see, those it matched, where it is registered and
  // where it is posed.
  double registered_context_share = 0;
  double posed_context_share = 0;
};

// The evidence that `views` (of the same two sub-models, either way round)
// link them, and the similarity between the two: from the 3D-3D
// correspondences of the points the shots see in both when there are
// min_link_points of them, else from the shots' two poses (two shots at
// least: one fixes no scale); each mapped point must reproject in every
// shot; and each shot must have matched the context its two poses predict
// alike. Nothing when a test of SubModelOptions fails (`why_not` then names
// it).
std::optional<SubModelLink> FindSubModelLink(const Reconstruction& reconstruction,
                                             const std::vector<SubModelView>& views,
                                             const SubModelOptions& options,
                                             std::string* why_not = nullptr);

// Merges the link's smaller sub-model into the larger (registered images;
// ties: into the link's own), fuses its same points, and returns the
// surviving sub-model and the fused points.
struct SubModelMerge {
  model_t model_id = kInvalidModelId;
  std::vector<point3D_t> fused_points;
};
SubModelMerge MergeSubModels(const SubModelLink& link, Reconstruction* reconstruction);

}  // namespace flysfm
