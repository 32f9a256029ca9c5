#include "core/registration.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <stdexcept>
#include <unordered_map>
#include <unordered_set>

namespace flysfm {

std::map<model_t, std::vector<Correspondence2D3D>> Find2D3DCorrespondences(
    const Reconstruction& reconstruction, const MatchStore& matches, image_t image_id) {
  const Image& image = reconstruction.image(image_id);
  std::map<model_t, std::map<point2D_t, std::map<point3D_t, int>>> votes;
  for (const image_t other_id : matches.Neighbours(image_id)) {
    const Image& other = reconstruction.image(other_id);
    if (!other.IsRegistered()) continue;
    auto& model_votes = votes[other.model_id];
    for (const FeatureMatch& match : matches.Matches(image_id, other_id)) {
      const point3D_t point3D_id = other.points2D[match.idx2].point3D_id;
      if (point3D_id != kInvalidPoint3DId) ++model_votes[point2D_t(match.idx1)][point3D_id];
    }
  }
  std::map<model_t, std::vector<Correspondence2D3D>> correspondences;
  for (const auto& [model_id, model_votes] : votes) {
    std::map<point3D_t, std::pair<int, point2D_t>> owner;
    for (const auto& [point2D_idx, counts] : model_votes) {
      const auto best = std::max_element(
          counts.begin(), counts.end(),
          [](const auto& a, const auto& b) { return a.second < b.second; });
      auto [it, inserted] =
          owner.emplace(best->first, std::make_pair(best->second, point2D_idx));
      if (!inserted && it->second.first < best->second) {
        it->second = {best->second, point2D_idx};
      }
    }
    std::vector<Correspondence2D3D>& found = correspondences[model_id];
    found.reserve(owner.size());
    for (const auto& [point3D_id, support] : owner) {
      found.push_back({support.second, image.points2D[support.second].xy, point3D_id});
    }
  }
  return correspondences;
}

bool Registrar::Options::Check() const {
  return min_num_correspondences >= 4 && absolute_pose.Check() && densify.Check() &&
         densify_max_references >= 1 && densify_max_candidates >= 0;
}

Registrar::Registrar(const Options& options, const MatchStore* matches,
                     Reconstruction* reconstruction, LsmImageStore* lsm_images)
    : options_(options),
      matches_(matches),
      reconstruction_(reconstruction),
      lsm_images_(lsm_images) {
  if (!options_.Check()) throw std::invalid_argument("invalid registration options");
}

Registrar::Result Registrar::Register(image_t image_id, StageTimes* times) {
  Result result;
  const Camera& camera =
      reconstruction_->camera(reconstruction_->image(image_id).camera_id);
  std::vector<Correspondence2D3D> correspondences;
  std::vector<Eigen::Vector2d> pixels;
  std::vector<Eigen::Vector3d> points;
  const auto append = [&](const std::vector<Correspondence2D3D>& more) {
    for (const Correspondence2D3D& correspondence : more) {
      correspondences.push_back(correspondence);
      pixels.push_back(correspondence.pixel);
      points.push_back(reconstruction_->point3D(correspondence.point3D_id).xyz);
    }
    result.num_correspondences = int(correspondences.size());
  };

  AbsolutePoseResult pose;
  {
    ScopedStageTimer timer(&times->registration);
    std::map<model_t, std::vector<Correspondence2D3D>> per_model =
        Find2D3DCorrespondences(*reconstruction_, *matches_, image_id);
    const auto most = std::max_element(
        per_model.begin(), per_model.end(),
        [](const auto& a, const auto& b) { return a.second.size() < b.second.size(); });
    if (most != per_model.end()) {
      result.model_id = most->first;
      append(most->second);
    }
    if (result.num_correspondences < options_.min_num_correspondences) {
      result.reason = "too few 2D-3D correspondences (" +
                      std::to_string(result.num_correspondences) + ")";
      return result;
    }
    pose = EstimateAbsolutePose(camera, pixels, points, options_.absolute_pose);
    if (!pose.success) {
      result.reason = "no pose from " + std::to_string(result.num_correspondences) +
                      " 2D-3D correspondences";
      return result;
    }
  }

  if (options_.lsm_densification) {
    std::vector<Correspondence2D3D> densified;
    {
      ScopedStageTimer timer(&times->lsm);
      densified = Densify(image_id, result.model_id, pose.cam_from_world, correspondences);
    }
    if (!densified.empty()) {
      ScopedStageTimer timer(&times->registration);
      result.num_densified = int(densified.size());
      append(densified);
      pose = ReestimateAbsolutePose(camera, pixels, points, pose.cam_from_world,
                                    options_.absolute_pose);
    }
  }

  ScopedStageTimer timer(&times->registration);
  reconstruction_->RegisterImage(image_id, pose.cam_from_world, result.model_id);
  for (std::size_t i = 0; i < correspondences.size(); ++i) {
    if (!pose.inlier_mask[i]) continue;
    const Correspondence2D3D& correspondence = correspondences[i];
    const point2D_t point2D_idx =
        correspondence.point2D_idx != kInvalidPoint2DIdx
            ? correspondence.point2D_idx
            : reconstruction_->AddPoint2D(image_id, correspondence.pixel);
    reconstruction_->AddObservation(correspondence.point3D_id, {image_id, point2D_idx});
  }
  result.num_pose_inliers = pose.num_inliers;
  result.success = true;
  return result;
}

std::vector<Correspondence2D3D> Registrar::Densify(
    image_t image_id, model_t model_id, const Rigid3d& cam_from_world,
    const std::vector<Correspondence2D3D>& correspondences) {
  // The image is searched whole; a waiting image kept only as windows
  // registers without densification.
  LsmView image{lsm_images_->SearchPyramid(image_id),
                reconstruction_->camera(reconstruction_->image(image_id).camera_id),
                cam_from_world, nullptr};
  if (image.pyramid.empty()) return {};
  // A reference gives templates from the windows the store keeps around its
  // points.
  const int reach = LsmTemplateReach(options_.densify.lsm);
  const int shifted_reach = reach + int(std::ceil(options_.densify.window_shift_px));
  const auto reference_view = [&](image_t id) {
    LsmImageStore* store = lsm_images_;
    return LsmView{{},
                   reconstruction_->camera(reconstruction_->image(id).camera_id),
                   *reconstruction_->image(id).cam_from_world,
                   [store, id, reach, shifted_reach](int level, const Eigen::Vector2d& point) {
                     return store->Window(id, level, point, level == 0 ? shifted_reach : reach);
                   }};
  };
  // References: the sub-model's registered neighbours sharing the most
  // verified matches.
  std::vector<std::pair<std::size_t, image_t>> neighbours;
  for (const image_t other_id : matches_->Neighbours(image_id)) {
    const Image& other = reconstruction_->image(other_id);
    if (other.IsRegistered() && other.model_id == model_id && lsm_images_->HasPixels(other_id)) {
      neighbours.emplace_back(matches_->NumMatches(image_id, other_id), other_id);
    }
  }
  std::sort(neighbours.rbegin(), neighbours.rend());
  neighbours.resize(std::min<std::size_t>(neighbours.size(), options_.densify_max_references));
  std::vector<LsmView> references;
  std::unordered_map<image_t, int> view_index;
  for (const auto& [count, id] : neighbours) {
    view_index[id] = int(references.size());
    references.push_back(reference_view(id));
  }

  // Candidates: the references' points without a correspondence here yet,
  // the best-established (longest tracks) first, up to the cap.
  std::unordered_set<point3D_t> taken;
  for (const Correspondence2D3D& correspondence : correspondences) {
    taken.insert(correspondence.point3D_id);
  }
  std::vector<point3D_t> candidate_ids;
  for (const auto& [count, id] : neighbours) {
    for (const Point2D& point2D : reconstruction_->image(id).points2D) {
      if (point2D.HasPoint3D() && taken.insert(point2D.point3D_id).second) {
        candidate_ids.push_back(point2D.point3D_id);
      }
    }
  }
  if (candidate_ids.empty()) return {};
  std::stable_sort(candidate_ids.begin(), candidate_ids.end(), [&](point3D_t a, point3D_t b) {
    return reconstruction_->point3D(a).track.size() > reconstruction_->point3D(b).track.size();
  });
  candidate_ids.resize(
      std::min<std::size_t>(candidate_ids.size(), options_.densify_max_candidates));
  std::vector<DensifyCandidate> candidates;
  candidates.reserve(candidate_ids.size());
  for (const point3D_t point3D_id : candidate_ids) {
    const Point3D& point = reconstruction_->point3D(point3D_id);
    DensifyCandidate candidate{point.xyz, {}};
    for (const TrackElement& element : point.track) {
      const auto it = view_index.find(element.image_id);
      if (it != view_index.end()) {
        candidate.observations.push_back(
            {it->second,
             reconstruction_->image(element.image_id).points2D[element.point2D_idx].xy});
      }
    }
    candidates.push_back(std::move(candidate));
  }

  const DensifyResult densified =
      flysfm::Densify(image, references, candidates, options_.densify);
  std::vector<Correspondence2D3D> added;
  added.reserve(densified.matches.size());
  for (const DensifyMatch& match : densified.matches) {
    added.push_back({kInvalidPoint2DIdx, match.point2D, candidate_ids[match.candidate]});
  }
  return added;
}

}  // namespace flysfm
