#pragma once

// The quality measures (quality/measures.h) of every point and registered
// image, kept current from the model's change sets at the cost of the change:
// an update recomputes the points and images a take of
// Reconstruction::TakeChanges() touched and keeps the rest.

#include <chrono>
#include <deque>
#include <functional>
#include <optional>
#include <string>
#include <unordered_map>
#include <unordered_set>
#include <vector>

#include "core/scene/reconstruction.h"
#include "quality/measures.h"

namespace flysfm {

class QualityTracker {
 public:
  struct Options {
    // Where the pixel noise of the uncertainties comes from.
    enum class Sigma {
      kFixed,     // sigma_px
      kModelRms,  // the model's RMS reprojection error (sigma_px while it has none)
      // A posteriori, per point and per image: the noise its own residuals
      // show (sum of squares over its redundancy, 2n - 3 for a point seen n
      // times, 2m - 6 for an image with m points), with the model's noise
      // per coordinate as a prior worth prior_redundancy residuals (sigma_px
      // while the model has none). A point whose rays fit worse than the
      // rest is less certain than its geometry alone says: on a rendered
      // session this ranks points by their true error better (Spearman
      // 0.53 against 0.43 with a fixed noise over 300 photos,
      // docs/quality.md).
      kAPosteriori,
    };
    Sigma sigma_source = Sigma::kAPosteriori;
    // Pixel noise, standard deviation per coordinate. 1 px: what SIFT
    // keypoints are good to on photos, before LSM sharpens them.
    double sigma_px = 1.0;
    // kAPosteriori: the model's noise counts as this many residuals of the
    // element's own. Small, so that an element's own fit decides; not 0, so
    // that a point seen twice (one residual of freedom) is not judged by
    // one number alone.
    double prior_redundancy = 1.0;
    // "Well covered": seen by at least min_views images under a largest
    // triangulation angle of at least min_angle_deg. Three views let a wrong
    // observation be told from a right one (two always agree with their
    // point); below about 10 degrees the depth's standard deviation exceeds
    // about 8 times the lateral one, Z / B for a stereo pair.
    int min_views = 3;
    double min_angle_deg = 10.0;
    // Per update, at most this long goes to measuring again what a bundle
    // adjustment only moved (a point whose observations are those it was
    // measured with, a registered image's pose); the rest waits, oldest
    // first, for the next update or Flush. New points and images, and those
    // whose observations came or went, are measured at once. A local BA in
    // a long session with revisits moves thousands of points seen by a
    // hundred images; a move is noise-sized, so a measure a few images late
    // is off by noise, and the cost per image stays flat.
    double refresh_budget_ms = 20.0;

    // Throws std::invalid_argument naming the bad option.
    void Check() const;
  };

  struct Summary {
    std::size_t points = 0;
    std::size_t images = 0;                // registered
    double sigma_px = 0;                   // the pixel noise the sigmas are for
    std::size_t well_covered_points = 0;   // min_views and min_angle_deg met
    double well_covered_share = 0;         // of the points; 0 without points
    double median_views = 0;
    double median_max_angle_deg = 0;
    double median_error_px = 0;
    double median_point_sigma = 0;         // over points with a defined sigma
    std::size_t undefined_point_sigmas = 0;
    double median_inliers = 0;
    double median_spread = 0;
    double median_center_sigma = 0;        // over images with a defined one
    std::size_t undefined_center_sigmas = 0;
    // What the updates did: the last one's and all of them.
    std::size_t last_recomputed_points = 0;
    std::size_t last_recomputed_images = 0;
    std::size_t recomputed_points = 0;
    std::size_t recomputed_images = 0;
    std::size_t updates = 0;
    double update_ms = 0;                  // all updates' time
    // Waiting to be measured again (moved by a bundle since their measure).
    std::size_t deferred_points = 0;
    std::size_t deferred_images = 0;
  };

  QualityTracker();
  explicit QualityTracker(Options options);

  // Measures everything again (a model read or resumed): the cost of the
  // model.
  void Rebuild(const Reconstruction& reconstruction);
  // Brings the measures up to date after `changes`, a take of
  // reconstruction.TakeChanges(). Every change since the last Rebuild or
  // Update must be in some take given here. Measures at once what is new
  // (points added or whose track changed, a track that only grew extended
  // by its new observations, images registered or deregistered); what a
  // bundle only moved, and images whose observations changed, within
  // options.refresh_budget_ms, oldest first; written intrinsics: everything
  // (docs/quality.md, "Kept current"). Returns its time in ms.
  double Update(const Reconstruction& reconstruction, const Reconstruction::Changes& changes);
  // Measures again everything still waiting from the refresh budget, so that
  // every measure is current (the end of a run, before its files). Returns
  // its time in ms.
  double Flush(const Reconstruction& reconstruction);

  // The pixel noise the sigmas are given for now: with kAPosteriori the
  // model's, each element's own scaled from it.
  double SigmaPx() const;
  // The measures, sigmas for SigmaPx(); nullopt for an unknown id.
  std::optional<PointQuality> Point(point3D_t point3D_id) const;
  std::optional<ImageQuality> Image(image_t image_id) const;
  // Every point's measures (O(points): for the files).
  std::unordered_map<point3D_t, PointQuality> Points() const;
  // Registered images by id, in id order.
  std::vector<std::pair<image_t, ImageQuality>> Images() const;
  // O(points + images): taken when the files are written.
  Summary Summarize() const;
  // The points the last Update or Rebuild measured again, in id order: the
  // live view resends their measures (an image's pose moved changes its
  // points' angles, not their positions).
  const std::vector<point3D_t>& LastRecomputedPoints() const { return last_recomputed_points_; }

  const Options& options() const { return options_; }

 private:
  struct CachedPoint {
    PointQuality quality;  // sigma for 1 px
    std::vector<image_t> images;  // its track's, for what its removal touches
    // Its information for 1 px (nullopt: a view had it behind), which an
    // extension of its track adds to.
    std::optional<Eigen::Matrix3d> information;
  };
  // What a changed point's track did since its measure.
  enum class TrackChange { kNone, kExtended, kOther };
  TrackChange TrackChangeOf(const Reconstruction& reconstruction, point3D_t point3D_id) const;
  // A track that only gained observations: their shares added to the cached
  // measure, at the cost of the new observations (the angle: of the new
  // rays against the track); the point is then queued for an exact measure.
  void ExtendPoint(const Reconstruction& reconstruction, point3D_t point3D_id);
  void Recompute(const Reconstruction& reconstruction, const Reconstruction::Changes& changes);
  // Runs `work` (given its start) with the counters of one update: what it
  // recomputed, its time, which it returns in ms.
  double Timed(const std::function<void(std::chrono::steady_clock::time_point)>& work);
  // Measures waiting elements, oldest first, until `budget_ms` from `start`.
  void Refresh(const Reconstruction& reconstruction, std::chrono::steady_clock::time_point start,
               double budget_ms);
  void RecomputePoint(const Reconstruction& reconstruction, point3D_t point3D_id);
  void ErasePoint(point3D_t point3D_id);
  PointQuality Scaled(PointQuality quality) const;
  // The pixel noise an element's sigma is for: SigmaPx(), or with
  // kAPosteriori its own, from `squared_error_sum` over `redundancy`.
  double NoiseOf(double squared_error_sum, double redundancy) const;
  double PointNoise(const PointQuality& quality) const;
  double ImageNoise(const ImageQuality& quality) const;

  Options options_;
  // Sigmas are stored for a 1 px noise and scaled when read: the model's RMS
  // changes with every image, and a covariance scales with sigma^2.
  std::unordered_map<point3D_t, CachedPoint> points_;
  std::unordered_map<image_t, ImageQuality> images_;
  double squared_error_sum_ = 0;
  std::size_t num_observations_ = 0;
  Summary counters_;
  std::vector<point3D_t> last_recomputed_points_;

  // Ids in the order they were first queued, each at most once.
  template <typename Id>
  class Queue {
   public:
    void Push(Id id) {
      if (!members_.insert(id).second) return;
      order_.push_back(id);
      // Erased ids leave stale entries behind: dropped when they outnumber
      // the members, so the queue stays the size of what waits.
      if (order_.size() > 2 * members_.size() + 1024) {
        std::deque<Id> kept;
        std::unordered_set<Id> seen;
        for (const Id queued : order_) {
          if (members_.count(queued) && seen.insert(queued).second) kept.push_back(queued);
        }
        order_ = std::move(kept);
      }
    }
    void Erase(Id id) { members_.erase(id); }
    // The oldest member; only when !empty().
    Id Pop() {
      while (!members_.count(order_.front())) order_.pop_front();
      const Id id = order_.front();
      order_.pop_front();
      members_.erase(id);
      return id;
    }
    bool empty() const { return members_.empty(); }
    std::size_t size() const { return members_.size(); }
    void clear() {
      members_.clear();
      order_.clear();
    }

   private:
    std::unordered_set<Id> members_;
    std::deque<Id> order_;  // may hold erased ids, skipped by Pop
  };
  Queue<point3D_t> dirty_points_;
  Queue<image_t> dirty_images_;
};

// The sigma source's name in summary.json and docs/defaults.md ("fixed",
// "model-rms", "a-posteriori"), and back; nullopt for an unknown name.
const char* SigmaSourceName(QualityTracker::Options::Sigma source);
std::optional<QualityTracker::Options::Sigma> SigmaSourceFromName(const std::string& name);

}  // namespace flysfm
