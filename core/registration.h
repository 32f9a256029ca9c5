#pragma once

// Registration of a new image against the model (the paper's Fig. 2, "image
// registration"): 2D-3D correspondences through the verified neighbours'
// tracks, P3P/EPnP inside RANSAC with a non-linear refinement, then LSM
// densification (visible but unmatched model points found by LSM with the
// first pose) and the pose again from all correspondences.

#include <map>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "core/scene/image_result.h"
#include "core/lsm_image_store.h"
#include "core/scene/reconstruction.h"
#include "geometry/absolute_pose.h"
#include "lsm/densify.h"
#include "matching/match_store.h"

namespace flysfm {

// A keypoint of the new image and the 3D point it sees. Densified ones have
// no keypoint yet (kInvalidPoint2DIdx): it is added only if the pose keeps it.
struct Correspondence2D3D {
  point2D_t point2D_idx = kInvalidPoint2DIdx;
  Eigen::Vector2d pixel = Eigen::Vector2d::Zero();
  point3D_t point3D_id = kInvalidPoint3DId;
};

// Each keypoint votes, through every registered verified neighbour, for the
// 3D point that neighbour's matched keypoint observes; a keypoint takes its
// best-supported point, and a point claimed by several keypoints goes to the
// one with most votes. Sub-models are apart (their frames differ): the
// correspondences come per sub-model the neighbours belong to.
std::map<model_t, std::vector<Correspondence2D3D>> Find2D3DCorrespondences(
    const Reconstruction& reconstruction, const MatchStore& matches, image_t image_id);

class Registrar {
 public:
  struct Options {
    // At least this many 2D-3D correspondences to try a pose.
    int min_num_correspondences = 20;
    AbsolutePoseOptions absolute_pose;
    // The paper's LSM densification; off only for the ablation.
    bool lsm_densification = true;
    DensifyOptions densify;
    // Densification looks for the points of this many registered neighbours
    // (those sharing the most verified matches), as the local BA's first
    // ripple does.
    int densify_max_references = 8;
    // At most this many points are tried per image, longest tracks first:
    // enough to steady the pose, while the per-image observation count (and
    // with it every later BA) stays bounded. On fr1_xyz 300 cost 25 ms more
    // of local BA per image than 150, for the same ATE.
    int densify_max_candidates = 150;

    bool Check() const;
  };

  struct Result {
    bool success = false;
    std::string reason;  // why not, when it failed
    // The sub-model tried: the one the most correspondences lead into.
    model_t model_id = kInvalidModelId;
    int num_correspondences = 0;  // before RANSAC, densified included
    int num_densified = 0;
    int num_pose_inliers = 0;
  };

  // The model, the matches and the LSM images must outlive the registrar.
  Registrar(const Options& options, const MatchStore* matches, Reconstruction* reconstruction,
            LsmImageStore* lsm_images);

  // On success the image is registered with its pose, in the sub-model the
  // most correspondences lead into, and observes its inlier points
  // (densified inliers become new keypoints). Adds registration and LSM
  // times to `times`.
  Result Register(image_t image_id, StageTimes* times);

 private:
  // Densified correspondences for `image_id` seen from `cam_from_world`, of
  // the points of sub-model `model_id`.
  std::vector<Correspondence2D3D> Densify(
      image_t image_id, model_t model_id, const Rigid3d& cam_from_world,
      const std::vector<Correspondence2D3D>& correspondences);

  Options options_;
  const MatchStore* matches_;
  Reconstruction* reconstruction_;
  LsmImageStore* lsm_images_;
};

}  // namespace flysfm
