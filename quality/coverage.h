#pragma once

// Coverage of the object's surface, and where to shoot next (docs/quality.md,
// "Coverage"). A coarse surface is carved out of the Delaunay tetrahedra of
// the model's points by the rays from each camera to the points it sees
// (a cell a ray crossed is empty space; the surface is where empty meets
// not-empty), so that an unphotographed side of the object is a surface too:
// the faces of the points' hull that no ray came near. Each face is judged as
// the points are ("well covered": enough views under a wide enough angle),
// from the cameras that see a corner of it and face it; the under-covered faces,
// grouped by the side of the object they face, give the suggested viewpoints.

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "core/scene/reconstruction.h"
#include "geometry/rigid3d.h"
#include "quality/quality_tracker.h"

namespace flysfm {

class Coverage {
 public:
  struct Options {
    // "Well covered", the points' rule (QualityTracker::Options, which says
    // why): at least min_views cameras facing the face, with a largest angle
    // between their rays of at least min_angle_deg.
    int min_views = QualityTracker::Options().min_views;
    double min_angle_deg = QualityTracker::Options().min_angle_deg;
    // A camera counts for a face when it sees one of its corners and looks
    // at it less obliquely than this: past about 75 degrees from the
    // normal a surface is foreshortened fourfold and its points are matched
    // poorly.
    double max_incidence_deg = 75.0;
    // The surface is coarse: at most this many points (evenly taken), and at
    // most this many rays per point carve it. Its cost is then bounded
    // whatever the model's size (about 0.1 s at the defaults).
    int max_points = 4000;
    int max_rays_per_point = 4;
    // Suggestions: at most this many, each for a side of the object with at
    // least this share of the reachable surface under-covered.
    int max_suggestions = 5;
    double min_suggestion_share = 0.01;
    // A side further round the object from every shot than a step gets a
    // step towards it from the nearest shot: the photographer's own spacing
    // round the object (the median angle from each shot to the nearest
    // other), at most this. SIFT takes some 30 degrees of change of
    // viewpoint on a facade seen square on, less at a grazing angle (a step
    // round a corner); and an area a step adds is seen once, so the next
    // step must overlap the last two.
    double max_step_deg = 20.0;

    // Throws std::invalid_argument naming the bad option.
    void Check() const;
  };

  enum class FaceClass {
    kWellCovered,
    kNarrowAngle,  // enough views, too narrow an angle
    kFewViews,     // fewer than min_views
    kUnderside,    // faces the ground: no photographer reaches it
    kOutOfReach,   // not seen from the heights and distance shot from (a roof)
  };

  struct Face {
    std::array<Eigen::Vector3d, 3> corners;
    Eigen::Vector3d normal = Eigen::Vector3d::Zero();  // unit, out of the object
    double area = 0;
    int views = 0;
    double max_angle_deg = 0;
    // Ground sampling distance: model units per pixel at the face, the
    // median over its views (0 without views).
    double gsd = 0;
    FaceClass face_class = FaceClass::kFewViews;
  };

  struct Suggestion {
    Eigen::Vector3d position = Eigen::Vector3d::Zero();   // projection centre
    Eigen::Vector3d direction = Eigen::Vector3d::Zero();  // unit, where it looks
    Rigid3d cam_from_world;  // looking along direction, image up along `up`
    double area_share = 0;   // of the reachable surface it would cover
    std::string reason;
    // A step towards the side (max_step_deg from the nearest shot), not yet
    // the view of it.
    bool step = false;
  };

  struct Summary {
    std::size_t points_used = 0;   // of the model's, for the surface
    std::size_t rays = 0;
    std::size_t faces = 0;
    double area = 0;               // reachable: undersides and out of reach excluded
    double well_covered_area = 0;
    double narrow_angle_area = 0;
    double few_views_area = 0;
    double underside_area = 0;
    double out_of_reach_area = 0;
    double well_covered_share = 0; // of the reachable area
    double median_gsd = 0;         // area-weighted over faces with views
    double ms = 0;
  };

  Coverage();
  explicit Coverage(Options options);

  // Measures `reconstruction` from scratch (the cost is bounded by the
  // options, not the model). Fewer than 4 points or 2 registered images:
  // no surface.
  void Update(const Reconstruction& reconstruction);

  const std::vector<Face>& faces() const { return faces_; }
  const std::vector<Suggestion>& suggestions() const { return suggestions_; }
  const Summary& summary() const { return summary_; }
  // The up direction the cameras agree on: photographers hold cameras
  // upright, so their images' x axes are level.
  const Eigen::Vector3d& up() const { return up_; }
  const Options& options() const { return options_; }

 private:
  Options options_;
  std::vector<Face> faces_;
  std::vector<Suggestion> suggestions_;
  Summary summary_;
  Eigen::Vector3d up_ = Eigen::Vector3d(0, -1, 0);
};

const char* FaceClassName(Coverage::FaceClass face_class);
// The colour a face is drawn in (surface.ply, the live view's legend): green
// well covered, orange too narrow an angle, red too few views, grey an
// underside, grey-blue out of reach.
std::array<std::uint8_t, 3> FaceClassColour(Coverage::FaceClass face_class);

}  // namespace flysfm
