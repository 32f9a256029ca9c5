#include "quality/quality_tracker.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <set>
#include <stdexcept>

#include "geometry/statistics.h"

namespace flysfm {

void QualityTracker::Options::Check() const {
  if (!(sigma_px > 0 && std::isfinite(sigma_px))) {
    throw std::invalid_argument("quality.sigma_px must be positive and finite");
  }
  if (!(prior_redundancy > 0 && std::isfinite(prior_redundancy))) {
    throw std::invalid_argument("quality.prior_redundancy must be positive and finite");
  }
  if (!(refresh_budget_ms >= 0)) {
    throw std::invalid_argument("quality.refresh_budget_ms must not be negative");
  }
  if (min_views < 2) throw std::invalid_argument("quality.min_views must be >= 2");
  if (!(min_angle_deg >= 0 && min_angle_deg < 180)) {
    throw std::invalid_argument("quality.min_angle_deg must be in [0, 180)");
  }
}

QualityTracker::QualityTracker() : QualityTracker(Options()) {}

QualityTracker::QualityTracker(Options options) : options_(options) { options_.Check(); }

void QualityTracker::ErasePoint(point3D_t point3D_id) {
  const auto cached = points_.find(point3D_id);
  if (cached == points_.end()) return;
  squared_error_sum_ -= cached->second.quality.squared_error_sum;
  num_observations_ -= std::size_t(cached->second.quality.views);
  points_.erase(cached);
}

void QualityTracker::RecomputePoint(const Reconstruction& reconstruction,
                                    point3D_t point3D_id) {
  ErasePoint(point3D_id);
  CachedPoint& cached = points_[point3D_id];
  cached.quality = MeasurePoint(reconstruction, point3D_id, 1.0, &cached.information);
  for (const TrackElement& element : reconstruction.point3D(point3D_id).track) {
    cached.images.push_back(element.image_id);
  }
  squared_error_sum_ += cached.quality.squared_error_sum;
  num_observations_ += std::size_t(cached.quality.views);
  ++counters_.last_recomputed_points;
  last_recomputed_points_.push_back(point3D_id);
}

QualityTracker::TrackChange QualityTracker::TrackChangeOf(const Reconstruction& reconstruction,
                                                          point3D_t point3D_id) const {
  const auto cached = points_.find(point3D_id);
  if (cached == points_.end()) return TrackChange::kOther;
  const std::vector<TrackElement>& track = reconstruction.point3D(point3D_id).track;
  const std::vector<image_t>& measured = cached->second.images;
  if (track.size() < measured.size()) return TrackChange::kOther;
  // Every measured image still in the track (a point has one observation
  // per image), in the same order: the engine appends to a track.
  for (std::size_t i = 0; i < measured.size(); ++i) {
    if (track[i].image_id != measured[i]) return TrackChange::kOther;
  }
  return track.size() == measured.size() ? TrackChange::kNone : TrackChange::kExtended;
}

void QualityTracker::ExtendPoint(const Reconstruction& reconstruction, point3D_t point3D_id) {
  CachedPoint& cached = points_.at(point3D_id);
  const Point3D& point = reconstruction.point3D(point3D_id);
  const std::size_t old_views = cached.images.size();
  PointQuality& quality = cached.quality;
  double error_sum = quality.error_px * double(old_views);
  double added_squared = 0;
  double max_angle = quality.max_angle_deg * M_PI / 180.0;
  for (std::size_t i = old_views; i < point.track.size(); ++i) {
    const TrackElement& element = point.track[i];
    const flysfm::Image& image = reconstruction.image(element.image_id);
    const double error =
        reconstruction.ReprojectionError(element.image_id, element.point2D_idx, point.xyz);
    error_sum += error;
    added_squared += error * error;
    if (cached.information) {
      const PointView view{*image.cam_from_world, &reconstruction.camera(image.camera_id)};
      const std::optional<Eigen::Matrix3d> share = ViewInformation(point.xyz, view);
      if (share) {
        *cached.information += *share;
      } else {
        cached.information.reset();
      }
    }
    const Eigen::Vector3d ray = point.xyz - ProjectionCenter(*image.cam_from_world);
    for (std::size_t j = 0; j < i; ++j) {
      const flysfm::Image& other = reconstruction.image(point.track[j].image_id);
      max_angle = std::max(
          max_angle, RayAngle(ray, point.xyz - ProjectionCenter(*other.cam_from_world)));
    }
    cached.images.push_back(element.image_id);
  }
  const std::size_t added = point.track.size() - old_views;
  quality.views = int(point.track.size());
  quality.error_px = error_sum / double(point.track.size());
  quality.squared_error_sum += added_squared;
  quality.max_angle_deg = max_angle * 180.0 / M_PI;
  quality.sigma.reset();
  if (cached.information && point.track.size() >= 2) {
    if (const std::optional<Eigen::Matrix3d> covariance =
            CovarianceFromInformation(*cached.information, 1.0)) {
      quality.sigma = LargestStdDev(*covariance);
    }
  }
  squared_error_sum_ += added_squared;
  num_observations_ += added;
  ++counters_.last_recomputed_points;
  last_recomputed_points_.push_back(point3D_id);
  // The point moved as its track grew (triangulated again, adjusted): the
  // exact measure within the refresh budget.
  dirty_points_.Push(point3D_id);
}

namespace {

Reconstruction::Changes Everything(const Reconstruction& reconstruction) {
  Reconstruction::Changes everything;
  for (const auto& [id, point] : reconstruction.points3D()) everything.added_points.insert(id);
  for (const auto& [id, image] : reconstruction.images()) everything.changed_images.insert(id);
  return everything;
}

}  // namespace

void QualityTracker::Rebuild(const Reconstruction& reconstruction) {
  Reconstruction::Changes everything;
  everything.changed_cameras = true;
  Update(reconstruction, everything);
}

double QualityTracker::Update(const Reconstruction& reconstruction,
                              const Reconstruction::Changes& changes) {
  const double ms = Timed([&](std::chrono::steady_clock::time_point start) {
    if (changes.changed_cameras) {
      // Intrinsics move every projection: all of it again (a global BA's
      // change, which cost the model's size already).
      points_.clear();
      images_.clear();
      dirty_points_.clear();
      dirty_images_.clear();
      squared_error_sum_ = 0;
      num_observations_ = 0;
      Recompute(reconstruction, Everything(reconstruction));
    } else {
      Recompute(reconstruction, changes);
    }
    Refresh(reconstruction, start, options_.refresh_budget_ms);
  });
  ++counters_.updates;
  return ms;
}

double QualityTracker::Flush(const Reconstruction& reconstruction) {
  return Timed([&](std::chrono::steady_clock::time_point start) {
    Refresh(reconstruction, start, std::numeric_limits<double>::infinity());
  });
}

double QualityTracker::Timed(
    const std::function<void(std::chrono::steady_clock::time_point)>& work) {
  const auto start = std::chrono::steady_clock::now();
  counters_.last_recomputed_points = 0;
  counters_.last_recomputed_images = 0;
  last_recomputed_points_.clear();
  work(start);
  counters_.recomputed_points += counters_.last_recomputed_points;
  counters_.recomputed_images += counters_.last_recomputed_images;
  const double ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  counters_.update_ms += ms;
  return ms;
}

void QualityTracker::Refresh(const Reconstruction& reconstruction,
                             std::chrono::steady_clock::time_point start, double budget_ms) {
  const auto spent_ms = [&] {
    return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start)
        .count();
  };
  // Oldest first, images before points (an image's measure is one number a
  // photographer reads; its points are many); the clock read every few
  // elements, each costing microseconds.
  for (int n = 0; !dirty_images_.empty(); ++n) {
    if (n % 8 == 0 && spent_ms() >= budget_ms) return;
    const image_t id = dirty_images_.Pop();
    if (reconstruction.ExistsImage(id) && reconstruction.image(id).IsRegistered()) {
      images_[id] = MeasureImage(reconstruction, id, 1.0);
      ++counters_.last_recomputed_images;
    } else {
      images_.erase(id);
    }
  }
  for (int n = 0; !dirty_points_.empty(); ++n) {
    if (n % 64 == 0 && spent_ms() >= budget_ms) return;
    const point3D_t id = dirty_points_.Pop();
    if (reconstruction.ExistsPoint3D(id)) RecomputePoint(reconstruction, id);
  }
}

void QualityTracker::Recompute(const Reconstruction& reconstruction,
                               const Reconstruction::Changes& changes) {
  // Measured now: what is new to the measures, whatever it costs (bounded
  // by what the image brought).
  std::set<point3D_t> points;
  std::set<image_t> images;
  // Images whose observations came or went: measured now when new to the
  // tracker, else within the refresh budget (a thousand observations each,
  // and in a long session a new image's points reach dozens of them).
  std::set<image_t> observations_changed;
  // Images that see a point that moved or whose track changed: theirs
  // changed when their count of points did. A point a local BA only moved,
  // the image's pose held, turns that image's ray by about the noise over
  // the depth: its measures stay (docs/quality.md).
  std::set<image_t> seeing_changed;
  const auto track_images = [&](point3D_t point3D_id, std::set<image_t>* into) {
    const auto cached = points_.find(point3D_id);
    if (cached != points_.end()) into->insert(cached->second.images.begin(), cached->second.images.end());
    if (reconstruction.ExistsPoint3D(point3D_id)) {
      for (const TrackElement& element : reconstruction.point3D(point3D_id).track) {
        into->insert(element.image_id);
      }
    }
  };
  // A point whose observations are those its measure was taken with, which
  // only moved, waits for the refresh budget; one whose track only grew is
  // extended now at the cost of what it gained; any other is measured now.
  std::set<point3D_t> extended;
  const auto classify = [&](point3D_t point3D_id) {
    switch (TrackChangeOf(reconstruction, point3D_id)) {
      case TrackChange::kNone: dirty_points_.Push(point3D_id); break;
      case TrackChange::kExtended: extended.insert(point3D_id); break;
      case TrackChange::kOther: points.insert(point3D_id); break;
    }
  };
  for (const point3D_t id : changes.removed_points) {
    track_images(id, &observations_changed);
    ErasePoint(id);
    dirty_points_.Erase(id);
  }
  for (const point3D_t id : changes.added_points) {
    track_images(id, &observations_changed);
    if (reconstruction.ExistsPoint3D(id)) points.insert(id);
  }
  for (const point3D_t id : changes.changed_points) {
    track_images(id, &seeing_changed);
    if (reconstruction.ExistsPoint3D(id)) classify(id);
  }
  for (const image_t id : seeing_changed) {
    const auto cached = images_.find(id);
    if (cached == images_.end() || !reconstruction.ExistsImage(id) ||
        cached->second.inliers != reconstruction.image(id).num_points3D) {
      observations_changed.insert(id);
    }
  }
  // Registered now or deregistered: now; one measured before, whose pose a
  // bundle moved or whose observations changed: within the budget.
  const auto queue_image = [&](image_t image_id) {
    const bool measured = images_.count(image_id) && reconstruction.ExistsImage(image_id) &&
                          reconstruction.image(image_id).IsRegistered();
    if (measured) {
      dirty_images_.Push(image_id);
    } else {
      images.insert(image_id);
    }
  };
  for (const image_t id : observations_changed) queue_image(id);
  for (const image_t id : changes.changed_images) {
    queue_image(id);
    if (!reconstruction.ExistsImage(id)) continue;
    // Its points see it from elsewhere now; their positions did not move,
    // so the other images observing them keep their measures.
    for (const Point2D& point2D : reconstruction.image(id).points2D) {
      if (point2D.HasPoint3D()) classify(point2D.point3D_id);
    }
  }
  for (const point3D_t id : points) {
    dirty_points_.Erase(id);
    extended.erase(id);
    RecomputePoint(reconstruction, id);
  }
  for (const point3D_t id : extended) ExtendPoint(reconstruction, id);
  for (const image_t id : images) {
    dirty_images_.Erase(id);
    if (!reconstruction.ExistsImage(id) || !reconstruction.image(id).IsRegistered()) {
      images_.erase(id);
      continue;
    }
    images_[id] = MeasureImage(reconstruction, id, 1.0);
    ++counters_.last_recomputed_images;
  }
}

double QualityTracker::SigmaPx() const {
  if (num_observations_ == 0) return options_.sigma_px;
  const double squared_sum = std::max(0.0, squared_error_sum_);
  switch (options_.sigma_source) {
    case Options::Sigma::kFixed: return options_.sigma_px;
    case Options::Sigma::kModelRms: return std::sqrt(squared_sum / double(num_observations_));
    // Per coordinate: an observation's squared error sums two.
    case Options::Sigma::kAPosteriori:
      return std::sqrt(squared_sum / (2.0 * double(num_observations_)));
  }
  return options_.sigma_px;
}

double QualityTracker::NoiseOf(double squared_error_sum, double redundancy) const {
  const double model = SigmaPx();
  if (options_.sigma_source != Options::Sigma::kAPosteriori) return model;
  const double prior = options_.prior_redundancy;
  return std::sqrt((std::max(0.0, squared_error_sum) + prior * model * model) /
                   (std::max(0.0, redundancy) + prior));
}

double QualityTracker::PointNoise(const PointQuality& quality) const {
  return NoiseOf(quality.squared_error_sum, 2.0 * quality.views - 3.0);
}

double QualityTracker::ImageNoise(const ImageQuality& quality) const {
  return NoiseOf(quality.squared_error_sum, 2.0 * quality.inliers - 6.0);
}

PointQuality QualityTracker::Scaled(PointQuality quality) const {
  if (quality.sigma) *quality.sigma *= PointNoise(quality);
  return quality;
}

std::optional<PointQuality> QualityTracker::Point(point3D_t point3D_id) const {
  const auto cached = points_.find(point3D_id);
  if (cached == points_.end()) return std::nullopt;
  return Scaled(cached->second.quality);
}

std::optional<ImageQuality> QualityTracker::Image(image_t image_id) const {
  const auto cached = images_.find(image_id);
  if (cached == images_.end()) return std::nullopt;
  ImageQuality quality = cached->second;
  if (quality.center_sigma) *quality.center_sigma *= ImageNoise(quality);
  return quality;
}

std::unordered_map<point3D_t, PointQuality> QualityTracker::Points() const {
  std::unordered_map<point3D_t, PointQuality> points;
  points.reserve(points_.size());
  for (const auto& [id, cached] : points_) points.emplace(id, Scaled(cached.quality));
  return points;
}

std::vector<std::pair<image_t, ImageQuality>> QualityTracker::Images() const {
  std::vector<std::pair<image_t, ImageQuality>> images;
  images.reserve(images_.size());
  for (const auto& entry : images_) images.emplace_back(entry.first, *Image(entry.first));
  std::sort(images.begin(), images.end(),
            [](const auto& a, const auto& b) { return a.first < b.first; });
  return images;
}

QualityTracker::Summary QualityTracker::Summarize() const {
  Summary summary = counters_;
  summary.points = points_.size();
  summary.images = images_.size();
  summary.deferred_points = dirty_points_.size();
  summary.deferred_images = dirty_images_.size();
  summary.sigma_px = SigmaPx();
  std::vector<double> views, angles, errors, sigmas;
  for (const auto& [id, cached] : points_) {
    const PointQuality& point = cached.quality;
    views.push_back(point.views);
    angles.push_back(point.max_angle_deg);
    errors.push_back(point.error_px);
    if (point.sigma) {
      sigmas.push_back(*point.sigma * PointNoise(point));
    } else {
      ++summary.undefined_point_sigmas;
    }
    summary.well_covered_points +=
        point.views >= options_.min_views && point.max_angle_deg >= options_.min_angle_deg;
  }
  if (!points_.empty()) {
    summary.well_covered_share = double(summary.well_covered_points) / double(points_.size());
  }
  summary.median_views = Median(views);
  summary.median_max_angle_deg = Median(angles);
  summary.median_error_px = Median(errors);
  summary.median_point_sigma = Median(sigmas);
  std::vector<double> inliers, spreads, center_sigmas;
  for (const auto& [id, image] : images_) {
    inliers.push_back(image.inliers);
    spreads.push_back(image.spread);
    if (image.center_sigma) {
      center_sigmas.push_back(*image.center_sigma * ImageNoise(image));
    } else {
      ++summary.undefined_center_sigmas;
    }
  }
  summary.median_inliers = Median(inliers);
  summary.median_spread = Median(spreads);
  summary.median_center_sigma = Median(center_sigmas);
  return summary;
}

const char* SigmaSourceName(QualityTracker::Options::Sigma source) {
  switch (source) {
    case QualityTracker::Options::Sigma::kFixed: return "fixed";
    case QualityTracker::Options::Sigma::kModelRms: return "model-rms";
    case QualityTracker::Options::Sigma::kAPosteriori: return "a-posteriori";
  }
  return "?";
}

std::optional<QualityTracker::Options::Sigma> SigmaSourceFromName(const std::string& name) {
  for (const auto source :
       {QualityTracker::Options::Sigma::kFixed, QualityTracker::Options::Sigma::kModelRms,
        QualityTracker::Options::Sigma::kAPosteriori}) {
    if (name == SigmaSourceName(source)) return source;
  }
  return std::nullopt;
}

}  // namespace flysfm
