#pragma once

// The initial pair (the paper's Fig. 2, "initialisation"): while no model
// exists, every verified pair with a relative pose is remembered; the best
// is the one whose verified matches triangulate into the most points seen
// under a good angle.

#include <istream>
#include <ostream>
#include <vector>

#include "core/scene/reconstruction.h"
#include "geometry/focal_from_fundamental.h"
#include "geometry/two_view_geometry.h"
#include "matching/match_store.h"

namespace flysfm {

struct InitialPair {
  image_t image_id1 = kInvalidImageId;
  image_t image_id2 = kInvalidImageId;
  Rigid3d cam2_from_cam1;
  // Verified matches whose two-view triangulation lies in front of both
  // cameras, reprojects within the threshold and is seen under at least
  // Options::min_point_angle_deg; and their median angle.
  int num_points = 0;
  double median_tri_angle_deg = 0;
};

class Initializer {
 public:
  struct Options {
    // A pair needs this many verified matches to be considered.
    int min_num_inliers = 100;
    // ... and its well-triangulated points a median angle of at least this.
    // The paper asks for 60-120 deg on wide-baseline photo sets; a hand-held
    // video moves a few centimetres a second, so this is the smallest angle
    // that still fixes depth well (COLMAP's incremental mapper uses 16 deg
    // on photo sets).
    double min_tri_angle_deg = 4.0;
    // ... and at least this many such points.
    int min_num_points = 50;
    // A point counts when seen under this angle and reprojected within this
    // many pixels in both images.
    double min_point_angle_deg = 1.5;
    double max_error_px = 4.0;
    // Without a calibration: the focal length the remembered pairs' F agree
    // on replaces the guess when they clearly prefer it.
    FocalFromFundamentalOptions focal_from_fundamental;

    bool Check() const;
  };

  explicit Initializer(const Options& options);

  // Remembers a verified pair's geometry (cam2 = image_id2) until the model
  // exists. With guessed intrinsics (`intrinsics_known` false) a pair where
  // GRIC preferred F to E starts a model from E's pose as well: the guess
  // being off is what makes F fit better (fountain-P11 from a focal length
  // 34 % off: 14 of its first 15 pairs), and the global BAs of the
  // self-calibration correct the start. With known ones F winning means E
  // does not explain the matches.
  void AddPair(image_t image_id1, image_t image_id2, const TwoViewGeometry& geometry,
               bool intrinsics_known);

  // The focal length that the F of the remembered pairs between two images of
  // `camera_id` agree on (geometry/focal_from_fundamental; pairs where GRIC
  // chose H are left out), when they clearly prefer it to the camera's
  // (FocalFromFundamentals with the camera's focal length as reference).
  // Returns 1 and sets *focal_length then, else 0.
  int CorrectFocalLength(const Reconstruction& reconstruction, camera_t camera_id,
                         double* focal_length) const;
  // E = K2^T F K1 with the cameras as they are now, decomposed and refined on
  // the pair's verified matches, replaces each remembered pose: after a
  // camera's focal length changed, the poses found with the old one are
  // distorted. A pair left without a pose is forgotten.
  void RecomputePoses(const Reconstruction& reconstruction, const MatchStore& matches);

  // The remembered pairs that qualify, most well-triangulated points first.
  // Keypoints and cameras are read as they are now (after LSM refinement);
  // the matches are the pairs' verified ones in `matches`.
  // With `image_id`, only its pairs. Pairs of registered images are left out.
  std::vector<InitialPair> RankPairs(const Reconstruction& reconstruction,
                                     const MatchStore& matches,
                                     image_t image_id = kInvalidImageId) const;
  // Pairs with a registered image can start nothing any more.
  void ForgetRegistered(const Reconstruction& reconstruction);

  // A pair that failed to start a model is not tried again.
  void Discard(const InitialPair& pair);
  // The model exists: nothing to remember any more.
  void Clear() { pairs_.clear(); }

  // The remembered pairs, in the engine's checkpoint; Read throws
  // std::runtime_error on a truncated stream.
  void Write(std::ostream& out) const;
  void Read(std::istream& in);

 private:
  struct Candidate {
    image_t image_id1;
    image_t image_id2;
    Rigid3d cam2_from_cam1;
    // In pixels (zero where GRIC chose H: a plane fixes no focal length).
    Eigen::Matrix3d F;
  };

  Options options_;
  std::vector<Candidate> pairs_;
};

}  // namespace flysfm
