#include "core/sub_models.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <set>

#include "geometry/similarity.h"
#include "geometry/statistics.h"

namespace flysfm {

bool SubModelOptions::Check() const {
  return min_link_points >= 3 && link_candidates >= 0 && min_inlier_ratio >= 0 &&
         min_inlier_ratio <= 1 && max_relative_distance > 0 && min_reprojected_ratio >= 0 &&
         min_reprojected_ratio <= 1 && max_reprojection_error_px > 0 && min_context_ratio >= 0 &&
         min_context_ratio <= 1 && context_max_angle_deg > 0 && context_max_angle_deg < 180 &&
         context_max_distance_ratio >= 1 && absolute_pose.Check();
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

std::vector<point3D_t> RegisteredMatches(const Reconstruction& reconstruction,
                                         image_t image_id,
                                         const std::vector<Correspondence2D3D>& correspondences,
                                         const SubModelOptions& options) {
  const Image& image = reconstruction.image(image_id);
  const Camera& camera = reconstruction.camera(image.camera_id);
  std::vector<point3D_t> matches;
  for (const Correspondence2D3D& correspondence : correspondences) {
    const Eigen::Vector3d in_cam =
        *image.cam_from_world * reconstruction.point3D(correspondence.point3D_id).xyz;
    if (in_cam.z() > 0 && (camera.ImgFromCam(in_cam) - correspondence.pixel).norm() <
                              options.absolute_pose.max_error_px) {
      matches.push_back(correspondence.point3D_id);
    }
  }
  return matches;
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

// Of the points of one sub-model a shot should see under its pose there,
// how many it matched.
struct Context {
  std::size_t expected = 0;
  std::size_t matched = 0;
};

// The points the shot should see are those shown by its verified
// neighbours in the sub-model taken from about where its pose there puts it
// (their centres closer than the angle spans at the depth of what it
// matched), which lie in its view and which such
// an image shows from within that angle of the shot's ray and at a
// comparable distance: the points it would have matched were the pose
// right. Images further away (the other side of a wide gap a link bridges)
// predict nothing: what the shot matches across a wide baseline is sparse,
// however right the pose.
Context ContextOf(const Reconstruction& reconstruction, image_t shot_id,
                  const Rigid3d& cam_from_model, const std::set<point3D_t>& matched,
                  const std::vector<image_t>& neighbours, const SubModelOptions& options) {
  Context context;
  if (matched.empty()) return context;
  const Eigen::Vector3d centre = ProjectionCenter(cam_from_model);
  std::set<image_t> observers(neighbours.begin(), neighbours.end());
  std::vector<double> depths;
  for (const point3D_t point3D_id : matched) {
    const Point3D& point = reconstruction.point3D(point3D_id);
    depths.push_back((cam_from_model * point.xyz).z());
    for (const TrackElement& element : point.track) {
      if (neighbours.empty() && element.image_id != shot_id) observers.insert(element.image_id);
    }
  }
  const double max_angle = options.context_max_angle_deg * M_PI / 180;
  const double max_baseline = std::tan(max_angle) * Median(depths);
  std::vector<const Image*> references;
  for (const image_t image_id : observers) {
    const Image& image = reconstruction.image(image_id);
    if (image.IsRegistered() &&
        (ProjectionCenter(*image.cam_from_world) - centre).norm() <= max_baseline) {
      references.push_back(&image);
    }
  }
  const Camera& camera = reconstruction.camera(reconstruction.image(shot_id).camera_id);
  const auto in_view = [&](const Eigen::Vector3d& xyz) {
    const Eigen::Vector3d in_cam = cam_from_model * xyz;
    if (in_cam.z() <= 0) return false;
    const Eigen::Vector2d pixel = camera.ImgFromCam(in_cam);
    return pixel.x() >= 0 && pixel.y() >= 0 && pixel.x() < camera.width &&
           pixel.y() < camera.height;
  };
  const double min_cos = std::cos(max_angle);
  const auto seen_alike = [&](const Eigen::Vector3d& xyz, const Eigen::Vector3d& reference) {
    const Eigen::Vector3d from_shot = xyz - centre;
    const Eigen::Vector3d from_reference = xyz - reference;
    const double ratio = from_shot.norm() / from_reference.norm();
    return ratio <= options.context_max_distance_ratio &&
           ratio * options.context_max_distance_ratio >= 1 &&
           from_shot.dot(from_reference) >= min_cos * from_shot.norm() * from_reference.norm();
  };
  std::set<point3D_t> counted;
  for (const Image* reference : references) {
    const Eigen::Vector3d reference_centre = ProjectionCenter(*reference->cam_from_world);
    for (const Point2D& point2D : reference->points2D) {
      if (!point2D.HasPoint3D() || counted.count(point2D.point3D_id)) continue;
      const Eigen::Vector3d& xyz = reconstruction.point3D(point2D.point3D_id).xyz;
      if (!in_view(xyz) || !seen_alike(xyz, reference_centre)) continue;
      counted.insert(point2D.point3D_id);
      ++context.expected;
      context.matched += matched.count(point2D.point3D_id);
    }
  }
  return context;
}

double Share(const Context& context) {
  return context.expected == 0 ? 0 : double(context.matched) / double(context.expected);
}

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
  // Every test above agrees on a repeated structure: what is around it,
  // which the shots' poses predict in both sub-models, tells.
  Context registered, posed;
  for (const ShotInBoth& shot : shots) {
    const SubModelView& view = *shot.view;
    const Image& image = reconstruction.image(view.image_id);
    std::set<point3D_t> matched_registered, matched_posed;
    for (const point3D_t point3D_id : view.registered_matches) {
      if (reconstruction.ExistsPoint3D(point3D_id)) matched_registered.insert(point3D_id);
    }
    for (const Point2D& point2D : image.points2D) {
      if (view.registered_matches.empty() && point2D.HasPoint3D()) {
        matched_registered.insert(point2D.point3D_id);
      }
    }
    for (const Correspondence2D3D& correspondence : view.inliers) {
      if (reconstruction.ExistsPoint3D(correspondence.point3D_id)) {
        matched_posed.insert(correspondence.point3D_id);
      }
    }
    const Context in_registered =
        ContextOf(reconstruction, view.image_id, *image.cam_from_world, matched_registered,
                  view.registered_neighbours, options);
    const Context in_posed = ContextOf(reconstruction, view.image_id, view.cam_from_posed,
                                       matched_posed, view.posed_neighbours, options);
    registered.expected += in_registered.expected;
    registered.matched += in_registered.matched;
    posed.expected += in_posed.expected;
    posed.matched += in_posed.matched;
  }
  link.registered_context_share = Share(registered);
  link.posed_context_share = Share(posed);
  const auto percent = [](double share) { return std::to_string(int(std::lround(100 * share))); };
  // Without images near the shot in either, nothing predicts a context.
  const bool predicted = int(std::min(registered.expected, posed.expected)) >=
                         options.min_link_points;
  if (predicted && std::min(link.registered_context_share, link.posed_context_share) <
      options.min_context_ratio *
          std::max(link.registered_context_share, link.posed_context_share)) {
    return Refuse(why_not, "context unmatched: the shots matched " +
                               percent(link.posed_context_share) +
                               " % of the points they should see where posed, " +
                               percent(link.registered_context_share) +
                               " % where registered");
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
