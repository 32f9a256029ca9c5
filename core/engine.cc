#include "core/engine.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <map>
#include <stdexcept>

#include <opencv2/imgproc.hpp>

#include "core/scene_bundle.h"
#include "geometry/check.h"
#include "matching/image_decode.h"

namespace flysfm {
namespace {

class Stopwatch {
 public:
  double ElapsedMs() const {
    return std::chrono::duration<double, std::milli>(
               std::chrono::steady_clock::now() - start_)
        .count();
  }

 private:
  std::chrono::steady_clock::time_point start_ = std::chrono::steady_clock::now();
};

Eigen::Vector2d KeypointPixel(const Keypoint& keypoint) {
  return Eigen::Vector2d(keypoint.x, keypoint.y);
}

}  // namespace

const char* ImageStatusName(ImageStatus status) {
  switch (status) {
    case ImageStatus::kRegistered: return "registered";
    case ImageStatus::kPending: return "pending";
    case ImageStatus::kRejected: return "rejected";
  }
  return "unknown";
}

bool Engine::Options::Check() const {
  return two_view.Check() && absolute_pose.Check() && triangulation.Check() &&
         sift.Check() && retrieval.Check() && matching.Check() && lsm.Check() &&
         ba_tree.Check() && ba.Check() && global_ba.Check() &&
         densify.Check() && densify_max_references >= 1 && lsm_cache_megabytes >= 0 &&
         densify_max_candidates >= 0 &&
         max_verified_pairs >= 1 && ba_max_constant_observers >= 0 &&
         init_min_num_inliers >= 5 &&
         init_min_tri_angle_deg >= 0 && init_min_num_points >= 2 &&
         min_num_correspondences >= 4 && filter_max_error_px > 0 &&
         filter_min_tri_angle_deg >= 0 && unknown_focal_factor > 0;
}

BundleAdjuster::Options Engine::Options::LocalBundleOptions() {
  BundleAdjuster::Options options;
  // The block starts close to its optimum (each of its images was adjusted
  // when it registered): on fr1_xyz, 3 iterations gave the same ATE as 10
  // (0.998 cm on 150 frames, after the final global BA).
  options.max_num_iterations = 3;
  return options;
}

SiftOptions Engine::Options::DefaultSiftOptions() {
  SiftOptions options;
  // Matching grows with the square of the count and every later stage with
  // the count: 1 500 kept fr1_xyz's ATE of 2 000 (1.09 cm on 120 frames) at
  // a little over half the matching time.
  options.max_num_features = 1500;
  return options;
}

HierarchicalAssociationTree::Options Engine::Options::DefaultTreeOptions() {
  HierarchicalAssociationTree::Options options;
  // The paper's top-8 comes from photo sets. In a video the top-8 of the
  // top-8 are mostly new images again, and ripple 2 alone held 12 or more;
  // top-5 halves the refined block (about 12 images) at the same ATE.
  options.top_n = 5;
  return options;
}

TriangulationOptions Engine::Options::DefaultTriangulationOptions() {
  TriangulationOptions options;
  // A track has a few to a few tens of observations, so a few hundred pair
  // samples cover it; without a bound, a keypoint whose rays are all nearly
  // parallel (adjacent video frames) would draw the RANSAC maximum.
  options.ransac.max_iterations = 200;
  return options;
}

Engine::Engine(const Options& options, std::optional<Camera> camera,
               std::shared_ptr<const RetrievalModel> retrieval_model)
    : options_(options),
      known_camera_(std::move(camera)),
      retriever_(retrieval_model ? ImageRetriever(options.retrieval, retrieval_model)
                                 : ImageRetriever(options.retrieval)) {
  if (!options_.Check()) throw std::invalid_argument("invalid engine options");
  if (known_camera_ && !known_camera_->IsValid()) {
    throw std::invalid_argument("invalid camera " + known_camera_->ToString());
  }
  if (!known_camera_) {
    // Guessed intrinsics are only a start: every BA refines them.
    for (BundleAdjuster::Options* ba : {&options_.ba, &options_.global_ba}) {
      ba->refine_focal_length = true;
      ba->refine_extra_params = true;
    }
  }
}

PreparedFrame Engine::Prepare(const Frame& frame, const Options& options) {
  PreparedFrame prepared;
  prepared.frame.name = frame.name;
  prepared.frame.path = frame.path;
  prepared.frame.timestamp = frame.timestamp;
  prepared.frame.arrival = frame.arrival;
  Stopwatch stopwatch;
  DecodedImage decoded = frame.bytes.empty() ? DecodeImageFile(frame.path.string())
                                             : DecodeImageBytes(frame.bytes);
  prepared.decode_ms = stopwatch.ElapsedMs();
  if (!decoded.ok()) {
    prepared.error = std::move(decoded.error);
    return prepared;
  }
  stopwatch = Stopwatch();
  prepared.image = std::move(decoded.image);
  prepared.exif_focal_length_px = decoded.exif_focal_length_px;
  cv::cvtColor(prepared.image, prepared.grey, cv::COLOR_BGR2GRAY);
  prepared.features = ExtractFeatures(prepared.image, prepared.grey, options.sift);
  prepared.features_ms = stopwatch.ElapsedMs();
  return prepared;
}

std::vector<ImageResult> Engine::AddImage(const Frame& frame) {
  return AddImage(Prepare(frame, options_));
}

std::vector<ImageResult> Engine::AddImage(PreparedFrame prepared) {
  const Stopwatch total;
  std::vector<ImageResult> results(1);
  ImageResult& result = results.front();
  result.name = prepared.frame.name;
  result.times.decode = prepared.decode_ms;
  result.times.features = prepared.features_ms;
  const double prepare_ms = prepared.decode_ms + prepared.features_ms;

  // Bad bytes are a counted rejection, never a crash.
  if (!prepared.error.empty()) {
    ++num_rejected_;
    result.status = ImageStatus::kRejected;
    result.reason = prepared.error;
    Finalize(&result);
    result.times.total = prepare_ms + total.ElapsedMs();
    return results;
  }

  std::vector<Eigen::Vector2d> keypoints;
  keypoints.reserve(prepared.features.keypoints.size());
  for (const Keypoint& keypoint : prepared.features.keypoints) {
    keypoints.push_back(KeypointPixel(keypoint));
  }
  const image_t image_id = reconstruction_.AddImage(
      prepared.frame.name, CameraFor(prepared.image.cols, prepared.image.rows,
                                     prepared.exif_focal_length_px),
      keypoints);
  result.image_id = image_id;
  result.num_features = prepared.features.size();
  ImageState& state = states_[image_id];
  state.grey = prepared.grey;

  // Retrieval: query the images seen so far, then insert this one.
  Stopwatch stopwatch;
  const RetrievalDescriptor descriptor =
      retriever_.Describe(prepared.image, prepared.features);
  const std::vector<RetrievalCandidate> candidates = retriever_.Query(descriptor);
  retriever_.Insert(int(image_id), prepared.image, prepared.features, descriptor);
  state.features = std::move(prepared.features);
  result.num_candidates = int(candidates.size());
  result.times.retrieval = stopwatch.ElapsedMs();

  // Matching, two-view geometry (GRIC) and LSM refinement, per candidate.
  // Until the model exists every candidate is matched: initialisation needs
  // the wide-baseline pairs, which rank low in retrieval.
  std::vector<char> lsm_refined;
  if (options_.lsm_refinement) lsm_refined.assign(result.num_features, 0);
  for (const RetrievalCandidate& candidate : candidates) {
    if (initialized_ && result.num_verified_pairs >= options_.max_verified_pairs) break;
    MatchAndVerify(image_id, image_t(candidate.image_id),
                   options_.lsm_refinement ? &lsm_refined : nullptr, &result);
  }

  // Initialisation while no model exists, else registration; either way the
  // image waits in the pending pool until it registers, and each image that
  // registers may let waiting ones register too.
  pending_.push_back(image_id);
  if (!initialized_) {
    TryInitialize(&result);
  } else {
    state.registered_neighbours_at_last_try = NumRegisteredVerifiedNeighbours(image_id);
    TryRegister(image_id, &result);
  }
  std::vector<ImageResult> retried = RetryPending(&result);
  results.insert(results.end(), std::make_move_iterator(retried.begin()),
                 std::make_move_iterator(retried.end()));
  if (result.status != ImageStatus::kRegistered && result.reason.empty()) {
    result.reason = "no initial pair yet";
  }
  Finalize(&result);
  result.times.total = prepare_ms + total.ElapsedMs();
  return results;
}

camera_t Engine::CameraFor(int width, int height,
                           std::optional<double> exif_focal_length_px) {
  const auto it = camera_by_size_.find({width, height});
  if (it != camera_by_size_.end()) return it->second;
  Camera camera;
  if (known_camera_) {
    camera = *known_camera_;
    camera.width = width;
    camera.height = height;
  } else {
    camera = Camera::FromFocal(
        CameraModelId::kSimpleRadial,
        exif_focal_length_px.value_or(options_.unknown_focal_factor * std::max(width, height)),
        width, height);
  }
  const camera_t camera_id = reconstruction_.AddCamera(camera);
  camera_by_size_[{width, height}] = camera_id;
  return camera_id;
}

void Engine::MatchAndVerify(image_t image_id, image_t other_id,
                            std::vector<char>* lsm_refined, ImageResult* result) {
  Stopwatch stopwatch;
  const ImageState& state = states_.at(image_id);
  const ImageState& other = states_.at(other_id);
  std::vector<FeatureMatch> raw = MatchDescriptors(
      state.features.descriptors, other.features.descriptors, options_.matching);
  result->times.matching += stopwatch.ElapsedMs();

  stopwatch = Stopwatch();
  std::vector<FeatureMatch> verified;
  if (int(raw.size()) >= options_.two_view.min_num_inliers_f) {
    const Image& image = reconstruction_.image(image_id);
    const Image& other_image = reconstruction_.image(other_id);
    std::vector<Eigen::Vector2d> points, other_points;
    for (const FeatureMatch& match : raw) {
      points.push_back(image.points2D[match.idx1].xy);
      other_points.push_back(other_image.points2D[match.idx2].xy);
    }
    PairGeometry pair{image_id, other_id,
                      EstimateCalibratedTwoViewGeometry(
                          reconstruction_.camera(image.camera_id), points,
                          reconstruction_.camera(other_image.camera_id), other_points,
                          options_.two_view)};
    if (pair.geometry.config != TwoViewConfiguration::kDegenerate) {
      for (std::size_t i = 0; i < raw.size(); ++i) {
        if (pair.geometry.inlier_mask[i]) verified.push_back(raw[i]);
      }
      if (!initialized_) pair_geometries_.push_back(std::move(pair));
    }
  }
  result->times.verification += stopwatch.ElapsedMs();

  // LSM: refine the new image's keypoint on the candidate's window; a match
  // that does not converge is an outlier. Keypoints refined in an earlier
  // pair keep that position.
  if (lsm_refined && !verified.empty()) {
    stopwatch = Stopwatch();
    Image& image = reconstruction_.image(image_id);
    const Image& other_image = reconstruction_.image(other_id);
    std::vector<Eigen::Vector2d> other_points, points;
    std::vector<int> to_refine;
    for (int i = 0; i < int(verified.size()); ++i) {
      if ((*lsm_refined)[verified[i].idx1]) continue;
      to_refine.push_back(i);
      other_points.push_back(other_image.points2D[verified[i].idx2].xy);
      points.push_back(image.points2D[verified[i].idx1].xy);
    }
    std::vector<char> keep(verified.size(), 1);
    if (!to_refine.empty()) {
      const RefineMatchesResult refined =
          RefineMatches(LsmPyramid(other_id).front(), LsmPyramid(image_id).front(),
                        other_points, points, options_.lsm);
      for (const int i : to_refine) keep[i] = 0;
      for (const int k : refined.inliers) {
        const FeatureMatch& match = verified[to_refine[k]];
        image.points2D[match.idx1].xy = refined.results[k].point2;
        (*lsm_refined)[match.idx1] = 1;
        keep[to_refine[k]] = 1;
      }
    }
    std::vector<FeatureMatch> kept;
    for (std::size_t i = 0; i < verified.size(); ++i) {
      if (keep[i]) kept.push_back(verified[i]);
    }
    result->num_lsm_rejected += int(verified.size() - kept.size());
    verified = std::move(kept);
    result->times.lsm += stopwatch.ElapsedMs();
  }
  if (int(verified.size()) >= options_.two_view.min_num_inliers_f) {
    ++result->num_verified_pairs;
  } else {
    verified.clear();
  }
  matches_.SetRawMatches(int(image_id), int(other_id), std::move(raw));
  matches_.SetVerifiedMatches(int(image_id), int(other_id), std::move(verified));
}

bool Engine::TryInitialize(ImageResult* result) {
  const Stopwatch stopwatch;
  // Candidates, best first: most inliers among the well-conditioned pairs.
  std::vector<const PairGeometry*> candidates;
  for (const PairGeometry& pair : pair_geometries_) {
    if (pair.geometry.has_pose &&
        pair.geometry.config != TwoViewConfiguration::kPanoramic &&
        pair.geometry.num_inliers >= options_.init_min_num_inliers &&
        pair.geometry.median_tri_angle_deg >= options_.init_min_tri_angle_deg) {
      candidates.push_back(&pair);
    }
  }
  std::sort(candidates.begin(), candidates.end(), [](const auto* a, const auto* b) {
    return a->geometry.num_inliers > b->geometry.num_inliers;
  });
  for (const PairGeometry* pair : candidates) {
    const image_t id1 = pair->image_id1;
    const image_t id2 = pair->image_id2;
    reconstruction_.RegisterImage(id1, Rigid3d());
    reconstruction_.RegisterImage(id2, pair->geometry.cam2_from_cam1);
    Triangulate(id1);
    if (int(reconstruction_.NumPoints3D()) >= options_.init_min_num_points) {
      AdjustAndFilter(id2, result);
    }
    if (int(reconstruction_.NumPoints3D()) >= options_.init_min_num_points) {
      initialized_ = true;
      pair_geometries_.clear();  // only needed until the model exists
      result->times.registration += stopwatch.ElapsedMs();
      return true;
    }
    reconstruction_.DeRegisterImage(id1);
    reconstruction_.DeRegisterImage(id2);
  }
  // Pairs that failed stay candidates only while new images may add points;
  // a failed pair is not tried again.
  pair_geometries_.erase(
      std::remove_if(pair_geometries_.begin(), pair_geometries_.end(),
                     [&](const PairGeometry& pair) {
                       return std::find(candidates.begin(), candidates.end(), &pair) !=
                              candidates.end();
                     }),
      pair_geometries_.end());
  result->times.registration += stopwatch.ElapsedMs();
  return false;
}

std::vector<std::pair<point2D_t, point3D_t>> Engine::Find2D3DCorrespondences(
    image_t image_id) {
  // Each keypoint votes, through every registered verified neighbour, for the
  // 3D point that neighbour's matched keypoint observes.
  std::map<point2D_t, std::map<point3D_t, int>> votes;
  for (const int other_id : matches_.VerifiedNeighbours(int(image_id))) {
    const Image& other = reconstruction_.image(image_t(other_id));
    if (!other.IsRegistered()) continue;
    for (const FeatureMatch& match : matches_.VerifiedMatches(int(image_id), other_id)) {
      const point3D_t point3D_id = other.points2D[match.idx2].point3D_id;
      if (point3D_id != kInvalidPoint3DId) ++votes[point2D_t(match.idx1)][point3D_id];
    }
  }
  // The best-supported point per keypoint; a point claimed by several
  // keypoints goes to the one with most votes.
  std::map<point3D_t, std::pair<int, point2D_t>> owner;
  for (const auto& [point2D_idx, counts] : votes) {
    const auto best = std::max_element(
        counts.begin(), counts.end(),
        [](const auto& a, const auto& b) { return a.second < b.second; });
    auto [it, inserted] = owner.emplace(best->first, std::make_pair(best->second, point2D_idx));
    if (!inserted && it->second.first < best->second) {
      it->second = {best->second, point2D_idx};
    }
  }
  std::vector<std::pair<point2D_t, point3D_t>> correspondences;
  for (const auto& [point3D_id, support] : owner) {
    correspondences.emplace_back(support.second, point3D_id);
  }
  return correspondences;
}

bool Engine::TryRegister(image_t image_id, ImageResult* result) {
  Stopwatch stopwatch;
  std::vector<std::pair<point2D_t, point3D_t>> correspondences =
      Find2D3DCorrespondences(image_id);
  result->num_correspondences = int(correspondences.size());
  if (int(correspondences.size()) < options_.min_num_correspondences) {
    result->times.registration += stopwatch.ElapsedMs();
    result->reason = "too few 2D-3D correspondences (" +
                     std::to_string(correspondences.size()) + ")";
    return false;
  }
  const Image& image = reconstruction_.image(image_id);
  const Camera& camera = reconstruction_.camera(image.camera_id);
  const auto estimate = [&]() {
    std::vector<Eigen::Vector2d> pixels;
    std::vector<Eigen::Vector3d> points;
    for (const auto& [point2D_idx, point3D_id] : correspondences) {
      pixels.push_back(reconstruction_.image(image_id).points2D[point2D_idx].xy);
      points.push_back(reconstruction_.point3D(point3D_id).xyz);
    }
    return EstimateAbsolutePose(camera, pixels, points, options_.absolute_pose);
  };
  AbsolutePoseResult pose = estimate();
  result->times.registration += stopwatch.ElapsedMs();
  if (!pose.success) {
    result->reason = "no pose from " + std::to_string(correspondences.size()) +
                     " 2D-3D correspondences";
    return false;
  }

  // LSM densification: more 2D-3D correspondences from visible model points,
  // then the pose again from all of them.
  if (options_.lsm_densification) {
    stopwatch = Stopwatch();
    result->num_densified = Densify(image_id, pose.cam_from_world, &correspondences);
    result->times.lsm += stopwatch.ElapsedMs();
    if (result->num_densified > 0) {
      stopwatch = Stopwatch();
      AbsolutePoseResult densified = estimate();
      if (densified.success) pose = std::move(densified);
      result->num_correspondences = int(correspondences.size());
      result->times.registration += stopwatch.ElapsedMs();
    }
  }

  stopwatch = Stopwatch();
  reconstruction_.RegisterImage(image_id, pose.cam_from_world);
  for (std::size_t i = 0; i < correspondences.size(); ++i) {
    if (pose.inlier_mask[i]) {
      reconstruction_.AddObservation(correspondences[i].second,
                                     {image_id, correspondences[i].first});
    }
  }
  result->num_pose_inliers = pose.num_inliers;
  result->times.registration += stopwatch.ElapsedMs();

  stopwatch = Stopwatch();
  result->num_new_points = Triangulate(image_id);
  result->times.triangulation += stopwatch.ElapsedMs();

  AdjustAndFilter(image_id, result);
  result->status = ImageStatus::kRegistered;
  result->reason.clear();
  return true;
}

int Engine::Densify(image_t image_id, const Rigid3d& cam_from_world,
                    std::vector<std::pair<point2D_t, point3D_t>>* correspondences) {
  const auto view_of = [&](image_t id, const Rigid3d& pose) {
    return LsmView{LsmPyramid(id), reconstruction_.camera(reconstruction_.image(id).camera_id),
                   pose};
  };
  // References: the registered neighbours sharing the most verified matches.
  std::vector<std::pair<int, image_t>> neighbours;
  for (const int other_id : matches_.VerifiedNeighbours(int(image_id))) {
    if (reconstruction_.image(image_t(other_id)).IsRegistered()) {
      neighbours.emplace_back(
          int(matches_.VerifiedMatches(int(image_id), other_id).size()), image_t(other_id));
    }
  }
  std::sort(neighbours.rbegin(), neighbours.rend());
  neighbours.resize(std::min<std::size_t>(neighbours.size(), options_.densify_max_references));
  std::vector<LsmView> references;
  std::unordered_map<image_t, int> view_index;
  for (const auto& [count, id] : neighbours) {
    view_index[id] = int(references.size());
    references.push_back(view_of(id, *reconstruction_.image(id).cam_from_world));
  }

  // Candidates: the references' points without a correspondence here yet.
  std::unordered_map<point3D_t, bool> taken;
  for (const auto& correspondence : *correspondences) taken[correspondence.second] = true;
  std::vector<DensifyCandidate> candidates;
  std::vector<point3D_t> candidate_ids;
  for (const auto& [count, id] : neighbours) {
    for (const Point2D& point2D : reconstruction_.image(id).points2D) {
      if (!point2D.HasPoint3D() || !taken.emplace(point2D.point3D_id, true).second) {
        continue;
      }
      const Point3D& point = reconstruction_.point3D(point2D.point3D_id);
      DensifyCandidate candidate{point.xyz, {}};
      for (const TrackElement& element : point.track) {
        const auto it = view_index.find(element.image_id);
        if (it != view_index.end()) {
          candidate.observations.push_back(
              {it->second,
               reconstruction_.image(element.image_id).points2D[element.point2D_idx].xy});
        }
      }
      candidates.push_back(std::move(candidate));
      candidate_ids.push_back(point2D.point3D_id);
    }
  }
  if (candidates.empty()) return 0;
  // The best-established points first (longest tracks), up to the cap.
  std::vector<int> order(candidates.size());
  for (std::size_t i = 0; i < order.size(); ++i) order[i] = int(i);
  std::stable_sort(order.begin(), order.end(), [&](int a, int b) {
    return reconstruction_.point3D(candidate_ids[a]).track.size() >
           reconstruction_.point3D(candidate_ids[b]).track.size();
  });
  order.resize(std::min<std::size_t>(order.size(), options_.densify_max_candidates));
  std::vector<DensifyCandidate> selected;
  std::vector<point3D_t> selected_ids;
  for (const int i : order) {
    selected.push_back(std::move(candidates[i]));
    selected_ids.push_back(candidate_ids[i]);
  }
  candidates = std::move(selected);
  candidate_ids = std::move(selected_ids);

  const DensifyResult densified = flysfm::Densify(view_of(image_id, cam_from_world),
                                                  references, candidates, options_.densify);
  for (const DensifyMatch& match : densified.matches) {
    const point2D_t point2D_idx = reconstruction_.AddPoint2D(image_id, match.point2D);
    correspondences->emplace_back(point2D_idx, candidate_ids[match.candidate]);
  }
  return int(densified.matches.size());
}

std::vector<LsmImage> Engine::LsmPyramid(image_t image_id) {
  const auto it = lsm_pyramids_.find(image_id);
  if (it != lsm_pyramids_.end()) {
    lsm_recency_.splice(lsm_recency_.begin(), lsm_recency_, it->second.recency);
    return it->second.levels;
  }
  CachedPyramid pyramid;
  pyramid.levels =
      BuildLsmPyramid(states_.at(image_id).grey, options_.densify.num_pyramid_levels);
  for (const LsmImage& level : pyramid.levels) pyramid.bytes += level.ByteSize();
  lsm_recency_.push_front(image_id);
  pyramid.recency = lsm_recency_.begin();
  lsm_cache_bytes_ += pyramid.bytes;
  std::vector<LsmImage> levels = pyramid.levels;
  lsm_pyramids_.emplace(image_id, std::move(pyramid));
  const std::size_t budget = std::size_t(options_.lsm_cache_megabytes) << 20;
  while (lsm_cache_bytes_ > budget && lsm_recency_.size() > 1) {
    const auto evicted = lsm_pyramids_.find(lsm_recency_.back());
    lsm_cache_bytes_ -= evicted->second.bytes;
    lsm_pyramids_.erase(evicted);
    lsm_recency_.pop_back();
  }
  return levels;
}

int Engine::Triangulate(image_t image_id) {
  const Image& image = reconstruction_.image(image_id);
  const std::size_t points_before = reconstruction_.NumPoints3D();

  // Per keypoint of this image: the registered keypoints matched to it that
  // observe nothing yet (a new track), and the points matched ones observe
  // (continuations of existing tracks).
  std::map<point2D_t, std::vector<TrackElement>> new_tracks;
  std::map<point2D_t, std::vector<point3D_t>> continuations;
  for (const int other_id : matches_.VerifiedNeighbours(int(image_id))) {
    const Image& other = reconstruction_.image(image_t(other_id));
    if (!other.IsRegistered()) continue;
    for (const FeatureMatch& match : matches_.VerifiedMatches(int(image_id), other_id)) {
      if (image.points2D[match.idx1].HasPoint3D()) continue;
      const point3D_t other_point = other.points2D[match.idx2].point3D_id;
      if (other_point != kInvalidPoint3DId) {
        continuations[point2D_t(match.idx1)].push_back(other_point);
      } else {
        new_tracks[point2D_t(match.idx1)].push_back({image_t(other_id), point2D_t(match.idx2)});
      }
    }
  }

  // Continuation: the point that reprojects best, if within the threshold and
  // not yet seen in this image.
  for (const auto& [point2D_idx, point3D_ids] : continuations) {
    double best_error = options_.triangulation.max_error_px;
    point3D_t best = kInvalidPoint3DId;
    for (const point3D_t point3D_id : point3D_ids) {
      const Point3D& point = reconstruction_.point3D(point3D_id);
      const bool seen_here =
          std::any_of(point.track.begin(), point.track.end(),
                      [&](const TrackElement& e) { return e.image_id == image_id; });
      const double error = reconstruction_.ReprojectionError(image_id, point2D_idx, point.xyz);
      if (!seen_here && error < best_error) {
        best_error = error;
        best = point3D_id;
      }
    }
    if (best != kInvalidPoint3DId) reconstruction_.AddObservation(best, {image_id, point2D_idx});
  }

  // New tracks: RANSAC multi-view triangulation over this keypoint and its
  // unobserved matches.
  const Keypoint* keypoints = states_.at(image_id).features.keypoints.data();
  const int num_keypoints = states_.at(image_id).features.size();
  for (auto& [point2D_idx, elements] : new_tracks) {
    if (image.points2D[point2D_idx].HasPoint3D()) continue;
    elements.insert(elements.begin(), {image_id, point2D_idx});
    std::vector<TriangulationObservation> observations;
    std::vector<TrackElement> usable;
    for (const TrackElement& element : elements) {
      const Image& observer = reconstruction_.image(element.image_id);
      // One observation per image, each keypoint still free.
      if (observer.points2D[element.point2D_idx].HasPoint3D() ||
          std::any_of(usable.begin(), usable.end(), [&](const TrackElement& e) {
            return e.image_id == element.image_id;
          })) {
        continue;
      }
      observations.push_back({*observer.cam_from_world,
                              &reconstruction_.camera(observer.camera_id),
                              observer.points2D[element.point2D_idx].xy});
      usable.push_back(element);
    }
    if (usable.size() < 2) continue;
    const TriangulationResult triangulated =
        EstimateTriangulation(observations, options_.triangulation);
    if (!triangulated.success || !triangulated.inlier_mask[0]) continue;
    std::vector<TrackElement> track;
    for (std::size_t i = 0; i < usable.size(); ++i) {
      if (triangulated.inlier_mask[i]) track.push_back(usable[i]);
    }
    std::array<std::uint8_t, 3> color = {0, 0, 0};
    if (int(point2D_idx) < num_keypoints) {
      const Keypoint& keypoint = keypoints[point2D_idx];
      color = {keypoint.r, keypoint.g, keypoint.b};
    }
    reconstruction_.AddPoint3D(triangulated.point, track, color);
  }
  return int(reconstruction_.NumPoints3D() - points_before);
}

void Engine::AdjustAndFilter(image_t image_id, ImageResult* result) {
  const Stopwatch stopwatch;
  HierarchicalAssociationTree::Options tree_options = options_.ba_tree;
  if (!options_.hierarchical_weights) {
    tree_options.k = 1.0;
    tree_options.fix_outermost_ripple = false;
  }
  const HierarchicalAssociationTree tree = HierarchicalAssociationTree::Build(
      int(image_id),
      [&](int id) { return RegisteredNeighbours(image_t(id), tree_options.top_n); },
      tree_options);
  std::unordered_map<image_t, double> weights;
  for (const auto& ripple : tree.ripples()) {
    for (const int id : ripple) weights[image_t(id)] = tree.WeightOf(id);
  }
  const SceneBundleResult adjusted =
      AdjustLocalBundle(weights, options_.ba, options_.ba_max_constant_observers,
                        &reconstruction_);
  result->ba_free_images = adjusted.summary.num_free_images;
  result->ba_images = adjusted.summary.num_images;
  result->ba_points = adjusted.summary.num_points;
  result->ba_iterations = adjusted.summary.num_iterations;
  reconstruction_.FilterPoints3D(adjusted.points, options_.filter_max_error_px,
                                 options_.filter_min_tri_angle_deg);
  result->times.ba += stopwatch.ElapsedMs();
}

std::vector<int> Engine::RegisteredNeighbours(image_t image_id, int n) const {
  std::vector<int> neighbours;
  // Pending images are interleaved in the ranking: ask for more.
  for (const RetrievalCandidate& candidate :
       retriever_.QueryInserted(int(image_id), 3 * n)) {
    if (reconstruction_.image(image_t(candidate.image_id)).IsRegistered()) {
      neighbours.push_back(candidate.image_id);
      if (int(neighbours.size()) == n) break;
    }
  }
  return neighbours;
}

int Engine::NumRegisteredVerifiedNeighbours(image_t image_id) const {
  int count = 0;
  for (const int other_id : matches_.VerifiedNeighbours(int(image_id))) {
    count += reconstruction_.image(image_t(other_id)).IsRegistered();
  }
  return count;
}

std::vector<ImageResult> Engine::RetryPending(ImageResult* new_image_result) {
  std::vector<ImageResult> results;
  // The new image reports into its own result; others get one each.
  const auto result_for = [&](image_t image_id) -> ImageResult* {
    if (new_image_result && new_image_result->image_id == image_id) {
      return new_image_result;
    }
    ImageResult& result = results.emplace_back();
    result.name = reconstruction_.image(image_id).name;
    result.image_id = image_id;
    return &result;
  };
  // Images registered already (the new one, or an initial pair) leave first.
  for (auto it = pending_.begin(); it != pending_.end();) {
    if (reconstruction_.image(*it).IsRegistered()) {
      Finalize(result_for(*it));
      it = pending_.erase(it);
    } else {
      ++it;
    }
  }
  if (!initialized_) return results;
  // Then every waiting image whose registered neighbourhood grew since its
  // last try, again while any registers.
  for (bool progress = true; progress;) {
    progress = false;
    for (auto it = pending_.begin(); it != pending_.end();) {
      ImageState& state = states_.at(*it);
      const int neighbours = NumRegisteredVerifiedNeighbours(*it);
      if (neighbours == 0 || neighbours == state.registered_neighbours_at_last_try) {
        ++it;
        continue;
      }
      state.registered_neighbours_at_last_try = neighbours;
      ImageResult scratch;
      scratch.image_id = *it;
      if (TryRegister(*it, &scratch)) {
        ImageResult* result = result_for(*it);
        if (result != new_image_result) {
          *result = scratch;
          result->name = reconstruction_.image(*it).name;
        } else {
          result->status = scratch.status;
          result->num_correspondences = scratch.num_correspondences;
          result->num_densified = scratch.num_densified;
          result->num_pose_inliers = scratch.num_pose_inliers;
          result->num_new_points = scratch.num_new_points;
        }
        Finalize(result);
        it = pending_.erase(it);
        progress = true;
      } else {
        ++it;
      }
    }
  }
  return results;
}

std::vector<ImageResult> Engine::Finish() {
  for (const image_t id : pending_) states_.at(id).registered_neighbours_at_last_try = -1;
  std::vector<ImageResult> results = RetryPending(nullptr);
  if (options_.final_global_ba && reconstruction_.NumRegisteredImages() >= 2) {
    AdjustGlobalBundle(options_.global_ba, &reconstruction_);
    reconstruction_.FilterAllPoints3D(options_.filter_max_error_px,
                                      options_.filter_min_tri_angle_deg);
  }
  reconstruction_.UpdatePointErrors();
  return results;
}

std::vector<std::string> Engine::PendingImageNames() const {
  std::vector<std::string> names;
  for (const image_t id : pending_) names.push_back(reconstruction_.image(id).name);
  return names;
}

void Engine::Finalize(ImageResult* result) const {
  result->model_images = int(reconstruction_.NumRegisteredImages());
  result->model_points = int(reconstruction_.NumPoints3D());
  if (result->image_id == kInvalidImageId) return;
  const Image& image = reconstruction_.image(result->image_id);
  if (image.IsRegistered()) {
    result->status = ImageStatus::kRegistered;
    result->reason.clear();
    result->cam_from_world = image.cam_from_world;
    result->num_observations = image.num_points3D;
  }
}

}  // namespace flysfm
