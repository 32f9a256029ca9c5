#include "core/sub_models.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <set>

#include "geometry/similarity.h"
#include "geometry/statistics.h"

namespace flysfm {

bool SubModelOptions::Check() const {
  return min_link_points >= 3 && link_candidates >= 0 && min_inlier_ratio >= 0 && min_inlier_ratio <= 1 &&
         max_relative_distance > 0 && min_reprojected_ratio >= 0 &&
         min_reprojected_ratio <= 1 && max_reprojection_error_px > 0 && absolute_pose.Check();
}

namespace {

std::nullopt_t Refuse(std::string* why_not, std::string reason) {
  if (why_not) *why_not = std::move(reason);
  return std::nullopt;
}

}  // namespace

std::optional<SubModelView> PoseInSubModel(
    const Reconstruction& reconstruction, image_t image_id, model_t other_id,
    const std::vector<Correspondence2D3D>& correspondences, const SubModelOptions& options,
    std::string* why_not) {
  const Image& image = reconstruction.image(image_id);
  if (int(correspondences.size()) < options.min_link_points) {
    return Refuse(why_not, std::to_string(correspondences.size()) + " correspondences");
  }
  std::vector<Eigen::Vector2d> pixels;
  std::vector<Eigen::Vector3d> points;
  for (const Correspondence2D3D& correspondence : correspondences) {
    pixels.push_back(correspondence.pixel);
    points.push_back(reconstruction.point3D(correspondence.point3D_id).xyz);
  }
  const AbsolutePoseResult pose = EstimateAbsolutePose(
      reconstruction.camera(image.camera_id), pixels, points, options.absolute_pose);
  if (!pose.success || pose.num_inliers < options.min_link_points) {
    return Refuse(why_not, "no pose from " + std::to_string(correspondences.size()) +
                               " correspondences (" + std::to_string(pose.num_inliers) +
                               " inliers)");
  }
  SubModelView view;
  view.image_id = image_id;
  view.registered_in = image.model_id;
  view.posed_in = other_id;
  view.cam_from_posed = pose.cam_from_world;
  for (std::size_t i = 0; i < correspondences.size(); ++i) {
    if (pose.inlier_mask[i]) view.inliers.push_back(correspondences[i]);
  }
  return view;
}

namespace {

// A view's shot in both frames.
struct ShotInBoth {
  const SubModelView* view;
  Rigid3d cam_from_own;
  Rigid3d cam_from_other;
};

// A point of the other sub-model seen by a shot: where, and the shot's pose
// in the own frame.
struct OtherObservation {
  Eigen::Vector2d pixel;
  const Rigid3d* cam_from_own;
  camera_t camera_id;
};

}  // namespace

std::optional<SubModelLink> FindSubModelLink(const Reconstruction& reconstruction,
                                             const std::vector<SubModelView>& views,
                                             const SubModelOptions& options,
                                             std::string* why_not) {
  if (views.empty()) return Refuse(why_not, "no shot");
  SubModelLink link;
  link.own_id = views.front().registered_in;
  link.other_id = views.front().posed_in;
  const auto count = [](std::size_t n) { return std::to_string(n); };

  // Each shot in both frames; the points of the other sub-model each sees;
  // and the 3D-3D correspondences of the keypoints that see a point in each.
  std::vector<ShotInBoth> shots;
  std::set<image_t> shot_ids;
  for (const SubModelView& view : views) {
    const Image& image = reconstruction.image(view.image_id);
    if (!image.IsRegistered() || image.model_id != view.registered_in) continue;
    if (view.registered_in == link.own_id && view.posed_in == link.other_id) {
      shots.push_back({&view, *image.cam_from_world, view.cam_from_posed});
    } else if (view.registered_in == link.other_id && view.posed_in == link.own_id) {
      shots.push_back({&view, view.cam_from_posed, *image.cam_from_world});
    } else {
      continue;
    }
    shot_ids.insert(view.image_id);
  }
  std::map<point3D_t, std::vector<OtherObservation>> other_seen;
  std::set<std::pair<point3D_t, point3D_t>> pair_set;
  std::vector<double> depths;
  for (const ShotInBoth& shot : shots) {
    const SubModelView& view = *shot.view;
    const Image& image = reconstruction.image(view.image_id);
    const bool in_own = view.registered_in == link.own_id;
    for (const Correspondence2D3D& correspondence : view.inliers) {
      // An earlier shot's points may have gone since (filtered, merged).
      if (!reconstruction.ExistsPoint3D(correspondence.point3D_id)) continue;
      const point3D_t seen = correspondence.point2D_idx == kInvalidPoint2DIdx
                                 ? kInvalidPoint3DId
                                 : image.points2D[correspondence.point2D_idx].point3D_id;
      const point3D_t own_point = in_own ? seen : correspondence.point3D_id;
      const point3D_t other_point = in_own ? correspondence.point3D_id : seen;
      if (own_point != kInvalidPoint3DId && other_point != kInvalidPoint3DId) {
        pair_set.insert({own_point, other_point});
      }
      if (!in_own) {
        depths.push_back((shot.cam_from_own * reconstruction.point3D(own_point).xyz).z());
      } else {
        other_seen[other_point].push_back(
            {correspondence.pixel, &shot.cam_from_own, image.camera_id});
      }
    }
    // The points the shot observes where it is registered.
    for (const Point2D& point2D : image.points2D) {
      if (!point2D.HasPoint3D()) continue;
      if (in_own) {
        depths.push_back(
            (shot.cam_from_own * reconstruction.point3D(point2D.point3D_id).xyz).z());
      } else {
        other_seen[point2D.point3D_id].push_back(
            {point2D.xy, &shot.cam_from_own, image.camera_id});
      }
    }
  }
  link.num_shots = int(shot_ids.size());
  if (depths.empty()) return Refuse(why_not, "no point seen");
  const double tolerance = options.max_relative_distance * Median(depths);
  const std::vector<std::pair<point3D_t, point3D_t>> pairs(pair_set.begin(), pair_set.end());

  if (int(pairs.size()) >= options.min_link_points) {
    // The points the shots see in both agree under one similarity.
    std::vector<Eigen::Vector3d> in_other, in_own;
    for (const auto& [own_point, other_point] : pairs) {
      in_own.push_back(reconstruction.point3D(own_point).xyz);
      in_other.push_back(reconstruction.point3D(other_point).xyz);
    }
    RansacOptions ransac;
    ransac.max_error = tolerance;
    const RansacResult<Sim3d> similarity = EstimateSimilarity(in_other, in_own, ransac);
    link.num_agreeing = similarity.num_inliers;
    if (!similarity.success || similarity.num_inliers < options.min_link_points ||
        similarity.num_inliers < options.min_inlier_ratio * double(pairs.size())) {
      return Refuse(why_not, count(similarity.num_inliers) + " of " + count(pairs.size()) +
                                 " points agree");
    }
    link.own_from_other = similarity.model;
    link.from_points = true;
    // Each agreeing point, mapped, in every image that observes its
    // counterpart: they see it from other directions than the shot.
    for (std::size_t i = 0; i < pairs.size(); ++i) {
      if (!similarity.inlier_mask[i]) continue;
      const Eigen::Vector3d mapped = link.own_from_other * in_other[i];
      const Point3D& own_point = reconstruction.point3D(pairs[i].first);
      const bool reprojects = std::all_of(
          own_point.track.begin(), own_point.track.end(), [&](const TrackElement& element) {
            return reconstruction.ReprojectionError(element.image_id, element.point2D_idx,
                                                    mapped) < options.max_reprojection_error_px;
          });
      if (reprojects) link.same_points.push_back(pairs[i]);
    }
    if (double(link.same_points.size()) < options.min_reprojected_ratio * link.num_agreeing ||
        int(link.same_points.size()) < options.min_link_points) {
      return Refuse(why_not, count(link.same_points.size()) + " of " +
                                 count(link.num_agreeing) + " agreeing points reproject");
    }
  } else {
    // Two shots or more posed in both: their rotations give the similarity's,
    // the spread of their centres its scale. One shot fixes no scale: it is
    // the centre of any.
    if (shots.size() < 2) {
      return Refuse(why_not, count(pairs.size()) + " points seen in both and one shot");
    }
    Eigen::Vector4d rotation_sum = Eigen::Vector4d::Zero();
    Eigen::Vector3d own_mean = Eigen::Vector3d::Zero(), other_mean = Eigen::Vector3d::Zero();
    const Eigen::Quaterniond first = shots.front().cam_from_own.rotation.conjugate() *
                                     shots.front().cam_from_other.rotation;
    for (const ShotInBoth& shot : shots) {
      Eigen::Quaterniond own_from_other =
          shot.cam_from_own.rotation.conjugate() * shot.cam_from_other.rotation;
      if (own_from_other.angularDistance(first) > options.max_relative_distance) {
        return Refuse(why_not, "the shots' rotations disagree");
      }
      if (own_from_other.coeffs().dot(first.coeffs()) < 0) {
        own_from_other.coeffs() *= -1;
      }
      rotation_sum += own_from_other.coeffs();
      own_mean += ProjectionCenter(shot.cam_from_own);
      other_mean += ProjectionCenter(shot.cam_from_other);
    }
    own_mean /= double(shots.size());
    other_mean /= double(shots.size());
    double own_spread = 0, other_spread = 0;
    for (const ShotInBoth& shot : shots) {
      own_spread += (ProjectionCenter(shot.cam_from_own) - own_mean).squaredNorm();
      other_spread += (ProjectionCenter(shot.cam_from_other) - other_mean).squaredNorm();
    }
    // Centres a pose's uncertainty apart fix no scale.
    if (std::sqrt(own_spread / double(shots.size())) < tolerance || other_spread <= 0) {
      return Refuse(why_not, "the shots are too close together");
    }
    const Eigen::Quaterniond rotation(rotation_sum.normalized());
    const double scale = std::sqrt(own_spread / other_spread);
    link.own_from_other = Sim3d(scale, rotation, own_mean - scale * (rotation * other_mean));
  }

  // The shots' two poses must be one under the similarity.
  for (const ShotInBoth& shot : shots) {
    const Rigid3d mapped = TransformPose(link.own_from_other, shot.cam_from_other);
    if ((ProjectionCenter(mapped) - ProjectionCenter(shot.cam_from_own)).norm() > tolerance ||
        mapped.rotation.angularDistance(shot.cam_from_own.rotation) >
            options.max_relative_distance) {
      return Refuse(why_not, "a shot's poses disagree");
    }
  }
  // The other sub-model's points, mapped, where the shots see them: from two
  // shots, their parallax checks the scale.
  std::size_t num_reprojected = 0;
  for (const auto& [other_point, observations] : other_seen) {
    const Eigen::Vector3d mapped = link.own_from_other * reconstruction.point3D(other_point).xyz;
    num_reprojected += std::all_of(
        observations.begin(), observations.end(), [&](const OtherObservation& observation) {
          const Eigen::Vector3d in_cam = *observation.cam_from_own * mapped;
          return in_cam.z() > 0 &&
                 (reconstruction.camera(observation.camera_id).ImgFromCam(in_cam) -
                  observation.pixel)
                         .norm() < options.max_reprojection_error_px;
        });
  }
  if (double(num_reprojected) < options.min_reprojected_ratio * double(other_seen.size()) ||
      int(num_reprojected) < options.min_link_points) {
    return Refuse(why_not, count(num_reprojected) + " of " + count(other_seen.size()) +
                               " points reproject");
  }
  return link;
}

SubModelMerge MergeSubModels(const SubModelLink& link, Reconstruction* reconstruction) {
  std::size_t own_size = 0, other_size = 0;
  for (const image_t image_id : reconstruction->RegisteredImageIds()) {
    const model_t model_id = reconstruction->image(image_id).model_id;
    own_size += model_id == link.own_id;
    other_size += model_id == link.other_id;
  }
  SubModelMerge merge;
  const bool into_own = own_size >= other_size;
  merge.model_id = into_own ? link.own_id : link.other_id;
  if (into_own) {
    reconstruction->MergeModels(link.other_id, link.own_id, link.own_from_other);
  } else {
    reconstruction->MergeModels(link.own_id, link.other_id, Inverse(link.own_from_other));
  }
  for (const auto& [own_point, other_point] : link.same_points) {
    // The larger sub-model's id survives, so that its points keep theirs.
    merge.fused_points.push_back(
        into_own ? reconstruction->MergePoints3D(own_point, other_point)
                 : reconstruction->MergePoints3D(other_point, own_point));
  }
  return merge;
}

}  // namespace flysfm
