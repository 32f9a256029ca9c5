#pragma once

// Triangulation of a newly registered image (the paper's Fig. 2, "RANSAC
// triangulation"), in the manner of COLMAP's incremental triangulator: its
// keypoints continue the tracks their matches observe, the rest start new
// tracks by RANSAC multi-view triangulation, and the tracks it touches are
// completed with matched keypoints of other registered images and merged
// where two points turn out to be one.

#include <array>
#include <cstdint>
#include <functional>

#include "core/scene/reconstruction.h"
#include "geometry/triangulation.h"
#include "matching/match_store.h"

namespace flysfm {

class Triangulator {
 public:
  struct Options {
    // New tracks. Its max_error_px is the one acceptance test of every
    // observation the triangulator adds: a continued or completed track must
    // reproject within it, and two points matched to each other are merged
    // when their joint position (the track-length weighted mean) reprojects
    // within it in every observation of both, as a new track's inliers must.
    TriangulationOptions triangulation;
    // Completion and merging of the tracks the image observes, as COLMAP's
    // triangulator does; off only to measure what they bring
    // (bench/bench_engine --ablation).
    bool complete_and_merge_tracks = true;

    bool Check() const;
  };

  struct Summary {
    int num_new_points = 0;
    int num_continued = 0;  // observations of the image added to existing tracks
    int num_completed = 0;  // observations of other images added to tracks
    int num_merged = 0;     // points joined into another

    void Add(const Summary& other) {
      num_new_points += other.num_new_points;
      num_continued += other.num_continued;
      num_completed += other.num_completed;
      num_merged += other.num_merged;
    }
  };

  // The colour of a keypoint, for new points.
  using ColorFunction = std::function<std::array<std::uint8_t, 3>(const TrackElement&)>;

  // The matches and the model must outlive the triangulator.
  Triangulator(const Options& options, const MatchStore* matches,
               Reconstruction* reconstruction, ColorFunction color);

  // `image_id` must be registered. Works on the image, its registered
  // verified neighbours and the tracks they share: its cost does not grow
  // with the model.
  Summary TriangulateImage(image_t image_id);

 private:
  class KeypointMatches;

  // Whether `point3D_id` reprojects within `max_error_px` at `element`.
  bool Reprojects(point3D_t point3D_id, const TrackElement& element, double max_error_px) const;
  bool TryMerge(point3D_t point3D_id1, point3D_t point3D_id2);

  Options options_;
  const MatchStore* matches_;
  Reconstruction* reconstruction_;
  ColorFunction color_;
};

}  // namespace flysfm
