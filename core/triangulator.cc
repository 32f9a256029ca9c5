#include "core/triangulator.h"

#include <algorithm>
#include <stdexcept>
#include <unordered_map>
#include <unordered_set>

namespace flysfm {

// Per keypoint of an image, its matches in registered images; built once per
// image and triangulation call.
class Triangulator::KeypointMatches {
 public:
  KeypointMatches(const MatchStore& matches, const Reconstruction& reconstruction)
      : matches_(matches), reconstruction_(reconstruction) {}

  const std::vector<TrackElement>& Of(const TrackElement& element) {
    static const std::vector<TrackElement> kNone;
    auto it = by_image_.find(element.image_id);
    if (it == by_image_.end()) it = by_image_.emplace(element.image_id, Build(element.image_id)).first;
    return element.point2D_idx < it->second.size() ? it->second[element.point2D_idx] : kNone;
  }

 private:
  std::vector<std::vector<TrackElement>> Build(image_t image_id) const {
    std::vector<std::vector<TrackElement>> lists(
        reconstruction_.image(image_id).points2D.size());
    const model_t model_id = reconstruction_.image(image_id).model_id;
    for (const image_t other_id : matches_.Neighbours(image_id)) {
      // A sub-model's tracks stay in its frame.
      const Image& other = reconstruction_.image(other_id);
      if (!other.IsRegistered() || other.model_id != model_id) continue;
      for (const FeatureMatch& match : matches_.Matches(image_id, other_id)) {
        lists[match.idx1].push_back({other_id, point2D_t(match.idx2)});
      }
    }
    return lists;
  }

  const MatchStore& matches_;
  const Reconstruction& reconstruction_;
  std::unordered_map<image_t, std::vector<std::vector<TrackElement>>> by_image_;
};

namespace {

bool TrackHasImage(const Point3D& point, image_t image_id) {
  return std::any_of(point.track.begin(), point.track.end(),
                     [&](const TrackElement& e) { return e.image_id == image_id; });
}

}  // namespace

bool Triangulator::Options::Check() const {
  return triangulation.Check();
}

Triangulator::Triangulator(const Options& options, const MatchStore* matches,
                           Reconstruction* reconstruction, ColorFunction color)
    : options_(options),
      matches_(matches),
      reconstruction_(reconstruction),
      color_(std::move(color)) {
  if (!options_.Check()) throw std::invalid_argument("invalid triangulator options");
}

bool Triangulator::Reprojects(point3D_t point3D_id, const TrackElement& element,
                              double max_error_px) const {
  return reconstruction_->ReprojectionError(element.image_id, element.point2D_idx,
                                            reconstruction_->point3D(point3D_id).xyz) <
         max_error_px;
}

Triangulator::Summary Triangulator::TriangulateImage(image_t image_id) {
  Summary summary;
  KeypointMatches keypoint_matches(*matches_, *reconstruction_);
  const double max_error_px = options_.triangulation.max_error_px;
  const auto is_free = [&](const TrackElement& element) {
    return !reconstruction_->image(element.image_id).points2D[element.point2D_idx].HasPoint3D();
  };
  const point2D_t num_points2D = point2D_t(reconstruction_->image(image_id).points2D.size());

  // Continuation: a free keypoint joins the matched point that reprojects
  // best, if within the threshold and not yet seen in this image.
  for (point2D_t idx = 0; idx < num_points2D; ++idx) {
    const TrackElement element{image_id, idx};
    if (!is_free(element)) continue;
    double best_error = max_error_px;
    point3D_t best = kInvalidPoint3DId;
    for (const TrackElement& other : keypoint_matches.Of(element)) {
      const point3D_t point3D_id =
          reconstruction_->image(other.image_id).points2D[other.point2D_idx].point3D_id;
      if (point3D_id == kInvalidPoint3DId || point3D_id == best) continue;
      const Point3D& point = reconstruction_->point3D(point3D_id);
      const double error = reconstruction_->ReprojectionError(image_id, idx, point.xyz);
      if (error < best_error && !TrackHasImage(point, image_id)) {
        best_error = error;
        best = point3D_id;
      }
    }
    if (best != kInvalidPoint3DId) {
      reconstruction_->AddObservation(best, element);
      ++summary.num_continued;
    }
  }

  // New tracks: RANSAC multi-view triangulation over a free keypoint, its
  // free matches, and their free matches in turn: a pair of registered
  // images whose rays were too close to triangulate before gets another try
  // with this image's ray.
  for (point2D_t idx = 0; idx < num_points2D; ++idx) {
    const TrackElement element{image_id, idx};
    if (!is_free(element)) continue;
    std::vector<TrackElement> usable = {element};
    const auto try_add = [&](const TrackElement& candidate) {
      const bool image_used =
          std::any_of(usable.begin(), usable.end(),
                      [&](const TrackElement& e) { return e.image_id == candidate.image_id; });
      if (!image_used && is_free(candidate)) usable.push_back(candidate);
    };
    for (const TrackElement& other : keypoint_matches.Of(element)) try_add(other);
    const std::size_t num_direct = usable.size();
    for (std::size_t i = 1; i < num_direct; ++i) {
      for (const TrackElement& other : keypoint_matches.Of(usable[i])) try_add(other);
    }
    if (usable.size() < 2) continue;
    std::vector<TriangulationObservation> observations;
    observations.reserve(usable.size());
    for (const TrackElement& observer : usable) {
      const Image& image = reconstruction_->image(observer.image_id);
      observations.push_back({*image.cam_from_world, &reconstruction_->camera(image.camera_id),
                              image.points2D[observer.point2D_idx].xy});
    }
    const TriangulationResult triangulated =
        EstimateTriangulation(observations, options_.triangulation);
    if (!triangulated.success || !triangulated.inlier_mask[0]) continue;
    std::vector<TrackElement> track;
    for (std::size_t i = 0; i < usable.size(); ++i) {
      if (triangulated.inlier_mask[i]) track.push_back(usable[i]);
    }
    reconstruction_->AddPoint3D(triangulated.point, track, color_(element));
    ++summary.num_new_points;
  }

  // Completion and merging of the tracks this image observes, through the
  // matches of their observations in this image and its neighbours.
  if (!options_.complete_and_merge_tracks) return summary;
  std::unordered_set<image_t> local = {image_id};
  for (const image_t other_id : matches_->Neighbours(image_id)) local.insert(other_id);
  std::vector<point3D_t> touched;
  for (const Point2D& point2D : reconstruction_->image(image_id).points2D) {
    if (point2D.HasPoint3D()) touched.push_back(point2D.point3D_id);
  }
  for (point3D_t point3D_id : touched) {
    if (!reconstruction_->ExistsPoint3D(point3D_id)) continue;  // merged away
    const std::vector<TrackElement> track = reconstruction_->point3D(point3D_id).track;
    for (const TrackElement& element : track) {
      if (!local.count(element.image_id)) continue;
      for (const TrackElement& other : keypoint_matches.Of(element)) {
        const Point3D& point = reconstruction_->point3D(point3D_id);
        if (TrackHasImage(point, other.image_id)) continue;
        const point3D_t other_point =
            reconstruction_->image(other.image_id).points2D[other.point2D_idx].point3D_id;
        if (other_point == kInvalidPoint3DId) {
          if (Reprojects(point3D_id, other, max_error_px)) {
            reconstruction_->AddObservation(point3D_id, other);
            ++summary.num_completed;
          }
        } else if (other_point != point3D_id && TryMerge(point3D_id, other_point)) {
          ++summary.num_merged;
        }
      }
    }
  }
  return summary;
}

bool Triangulator::TryMerge(point3D_t point3D_id1, point3D_t point3D_id2) {
  const Point3D& point1 = reconstruction_->point3D(point3D_id1);
  const Point3D& point2 = reconstruction_->point3D(point3D_id2);
  const double n1 = double(point1.track.size());
  const double n2 = double(point2.track.size());
  const Eigen::Vector3d merged = (n1 * point1.xyz + n2 * point2.xyz) / (n1 + n2);
  for (const Point3D* point : {&point1, &point2}) {
    for (const TrackElement& element : point->track) {
      if (!(reconstruction_->ReprojectionError(element.image_id, element.point2D_idx, merged) <
            options_.triangulation.max_error_px)) {
        return false;
      }
    }
  }
  reconstruction_->MergePoints3D(point3D_id1, point3D_id2);
  return true;
}

}  // namespace flysfm
