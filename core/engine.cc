#include "core/engine.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <map>
#include <set>
#include <stdexcept>
#include <utility>

#include "core/scene_bundle.h"
#include "matching/image_decode.h"

namespace flysfm {
namespace {

double MillisecondsSince(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start)
      .count();
}

// Adds `from`'s stage times to `to`'s.
void AddTimes(const StageTimes& from, StageTimes* to) {
  for (const auto& [name, member] : StageTimes::Stages()) to->*member += from.*member;
}

}  // namespace

bool Engine::Options::Finishing::Check() const {
  return num_threads >= 1 && function_tolerance >= 0 && max_share_of_run >= 0 &&
         min_seconds >= 0;
}

bool Engine::Options::Check(std::string* problem) const {
  const std::pair<bool, const char*> checks[] = {
      {decode.Check(), "decode"},
      {sift.Check(), "sift"},
      {retrieval.Check(), "retrieval"},
      {verification.Check(), "verification"},
      {max_verified_pairs >= 1, "max_verified_pairs (>= 1)"},
      {lsm_images.Check(), "lsm_images"},
      {lsm_images.num_pyramid_levels >= registration.densify.num_pyramid_levels,
       "lsm_images.num_pyramid_levels (>= registration.densify.num_pyramid_levels)"},
      {lsm_images.template_reach_px >= LsmTemplateReach(verification.lsm) &&
           lsm_images.template_reach_px >=
               LsmTemplateReach(registration.densify.lsm) +
                   std::ceil(registration.densify.window_shift_px),
       "lsm_images.template_reach_px (>= the LSM template reach plus the densification "
       "window shift)"},
      {lsm_images.coarse_template_reach_px >= LsmTemplateReach(registration.densify.lsm),
       "lsm_images.coarse_template_reach_px (>= the LSM template reach)"},
      {initialization.Check(), "initialization"},
      {registration.Check(), "registration"},
      {triangulation.Check(), "triangulation"},
      {ba_tree.Check(), "ba_tree"},
      {local_ba.Check(), "local_ba"},
      {ba_max_constant_observers >= 0, "ba_max_constant_observers (>= 0)"},
      {global_ba.Check(), "global_ba"},
      {outlier_quantile >= 0 && outlier_quantile < 1, "outlier_quantile (in [0, 1))"},
      {outlier_max_rounds >= 1, "outlier_max_rounds (>= 1)"},
      {filter_max_error_px > 0, "filter_max_error_px (> 0)"},
      {filter_min_tri_angle_deg >= 0, "filter_min_tri_angle_deg (>= 0)"},
      {unknown_focal_factor > 0, "unknown_focal_factor (> 0)"},
      {self_calibration_growth == 0 || self_calibration_growth > 1,
       "self_calibration_growth (0 or > 1)"},
      {self_calibration_converged_change >= 0, "self_calibration_converged_change (>= 0)"},
      {self_calibration_max_observations >= 1, "self_calibration_max_observations (>= 1)"},
      {self_calibration_min_iterations >= 1, "self_calibration_min_iterations (>= 1)"},
      {sub_models.Check(), "sub_models"},
      {refinement.Check(), "refinement"},
      {finishing.Check(), "finishing"},
  };
  for (const auto& [ok, name] : checks) {
    if (!ok) {
      if (problem) *problem = std::string("invalid engine option: ") + name;
      return false;
    }
  }
  return true;
}

namespace {

const Engine::Options& Checked(const Engine::Options& options) {
  std::string problem;
  if (!options.Check(&problem)) throw std::invalid_argument(problem);
  return options;
}

}  // namespace

Engine::Engine(const Options& options, std::optional<Camera> camera,
               std::shared_ptr<const RetrievalModel> retrieval_model)
    : options_(Checked(options)),
      known_camera_(std::move(camera)),
      retriever_(retrieval_model ? ImageRetriever(options.retrieval, retrieval_model)
                                 : ImageRetriever(options.retrieval)),
      lsm_images_(options.lsm_images),
      verifier_(options.verification, &reconstruction_, &lsm_images_),
      initializer_(options.initialization),
      registrar_(options.registration, &matches_, &reconstruction_, &lsm_images_),
      triangulator_(options.triangulation, &matches_, &reconstruction_,
                    [this](const TrackElement& element) -> std::array<std::uint8_t, 3> {
                      const std::vector<Keypoint>& keypoints =
                          features_.at(element.image_id).keypoints;
                      if (element.point2D_idx >= keypoints.size()) return {0, 0, 0};
                      const Keypoint& keypoint = keypoints[element.point2D_idx];
                      return {keypoint.r, keypoint.g, keypoint.b};
                    }) {
  if (known_camera_ && !known_camera_->IsValid()) {
    throw std::invalid_argument("invalid camera " + known_camera_->ToString());
  }
  if (!known_camera_) {
    // Guessed intrinsics are only a start, refined by the BAs that see every
    // image (the self-calibration schedule's, refinement's, Finish's),
    // principal point included (within the adjuster's bounds): on
    // fountain-P11 the centre instead of the true point, 16 px away, triples
    // the camera-centre error. The local BA holds them: against the images
    // it holds fixed, a focal length that moves bends the model instead of
    // carrying it, a little per image (fr1_xyz without K: 1 049 px for 517
    // after 120 frames, ATE 6.4 cm; held, 527 px and 1.09 cm).
    options_.global_ba.refine_focal_length = true;
    options_.global_ba.refine_extra_params = true;
    options_.global_ba.refine_principal_point = true;
  }
}

PreparedFrame Engine::Prepare(const Frame& frame, const Options& options) {
  PreparedFrame prepared;
  prepared.frame.name = frame.name;
  prepared.frame.path = frame.path;
  prepared.frame.timestamp = frame.timestamp;
  prepared.frame.arrival = frame.arrival;
  prepared.frame.source = frame.source;
  auto start = std::chrono::steady_clock::now();
  // Colours are read only at keypoints, which SIFT finds on a copy of at
  // most max_image_size pixels: a colour image reduced to about that size
  // gives them, and LSM reads the full-size grey.
  const int colour_long_side = options.sift.max_image_size;
  DecodedImage decoded =
      frame.bytes.empty()
          ? DecodeImageFile(frame.path.string(), options.decode, colour_long_side)
          : DecodeImageBytes(frame.bytes, options.decode, colour_long_side);
  prepared.decode_ms = MillisecondsSince(start);
  if (!decoded.ok()) {
    prepared.error = std::move(decoded.error);
    return prepared;
  }
  start = std::chrono::steady_clock::now();
  prepared.image = std::move(decoded.image);
  prepared.grey = std::move(decoded.grey);
  prepared.exif_focal_length_px = decoded.exif_focal_length_px;
  prepared.camera_identity = std::move(decoded.camera_identity);
  prepared.features = ExtractFeatures(prepared.image, prepared.grey, options.sift);
  prepared.features_ms = MillisecondsSince(start);
  return prepared;
}

std::vector<ImageResult> Engine::AddImage(const Frame& frame) {
  return AddImage(Prepare(frame, options_));
}

std::vector<ImageResult> Engine::AddImage(PreparedFrame prepared) {
  const auto call_start = std::chrono::steady_clock::now();
  std::vector<ImageResult> results = AddPreparedImage(std::move(prepared));
  work_seconds_ +=
      std::chrono::duration<double>(std::chrono::steady_clock::now() - call_start).count();
  return results;
}

std::vector<ImageResult> Engine::AddPreparedImage(PreparedFrame prepared) {
  std::vector<ImageResult> results(1);
  results[0].name = prepared.frame.name;
  results[0].times.decode = prepared.decode_ms;
  results[0].times.features = prepared.features_ms;

  // 1. Bad bytes are a counted rejection, never a crash.
  if (!prepared.error.empty()) {
    ++num_rejected_;
    results[0].status = ImageStatus::kRejected;
    results[0].reason = std::move(prepared.error);
    Finalize(&results[0]);
    return results;
  }

  // 2. The image and its features (extracted ahead) enter the model,
  // unregistered.
  image_t image_id;
  {
    ScopedStageTimer timer(&results[0].times.features);
    std::vector<Eigen::Vector2d> keypoints;
    keypoints.reserve(prepared.features.keypoints.size());
    for (const Keypoint& keypoint : prepared.features.keypoints) {
      keypoints.emplace_back(keypoint.x, keypoint.y);
    }
    image_id = reconstruction_.AddImage(
        prepared.frame.name,
        CameraFor(prepared),
        keypoints);
    reconstruction_.image(image_id).capture_time = prepared.frame.timestamp;
    lsm_images_.Add(image_id, prepared.grey);
    image_files_[image_id] = prepared.frame.path;
    results[0].image_id = image_id;
    results[0].num_features = prepared.features.size();
  }

  // 3. Retrieval: the top-N images seen so far, then this one is inserted.
  std::vector<RetrievalCandidate> candidates;
  {
    ScopedStageTimer timer(&results[0].times.retrieval);
    const RetrievalDescriptor descriptor =
        retriever_.Describe(prepared.image, prepared.features);
    candidates = retriever_.Query(descriptor);
    retriever_.Insert(image_id, prepared.image, prepared.features, descriptor);
    features_[image_id] = std::move(prepared.features);
    results[0].num_candidates = int(candidates.size());
  }

  // 4-5. Matching, two-view geometry (GRIC) and LSM refinement per candidate.
  VerifyPairs(image_id, candidates, &results[0]);

  // 6-10. Initialisation while no model exists, else registration,
  // triangulation and the hierarchical local BA. Either way the image waits
  // in the pending pool until it registers.
  pending_.Add(image_id);
  if (!initialized_) {
    Initialize(&results[0]);
  } else {
    pending_.MarkTried(image_id, NumRegisteredNeighbours(image_id));
    if (!RegisterAndExtend(image_id, &results[0]) && options_.sub_models.enabled) {
      Initialize(&results[0], image_id);
    }
  }

  // 11. Each image that registered may let waiting ones register too.
  RetryPending(&results);

  // 12. Images LSM will not search again keep only the windows around their
  // points that its templates read: memory stays bounded.
  {
    ScopedStageTimer timer(&results[0].times.lsm);
    KeepLsmWindows();
  }

  // 13. What refinement between shots (Refine) has to do now.
  refinement_.to_match.push_back(image_id);
  if (std::any_of(results.begin(), results.end(), [this](const ImageResult& result) {
        return reconstruction_.image(result.image_id).IsRegistered();
      })) {
    refinement_.adjust = true;
    refinement_.snooped_everything = false;
    refinement_.num_adjustments = 0;
  }
  if (results[0].status != ImageStatus::kRegistered && results[0].reason.empty()) {
    results[0].reason = "no initial pair yet";
  }
  for (ImageResult& result : results) Finalize(&result);
  return results;
}

camera_t Engine::CameraFor(const PreparedFrame& prepared) {
  const int width = prepared.grey.cols;
  const int height = prepared.grey.rows;
  const std::tuple<int, int, std::string> key{width, height, prepared.camera_identity};
  const auto it = camera_by_identity_.find(key);
  if (it != camera_by_identity_.end()) return it->second;
  Camera camera;
  if (known_camera_) {
    camera = *known_camera_;
    camera.width = width;
    camera.height = height;
  } else {
    camera = Camera::FromFocal(
        CameraModelId::kSimpleRadial,
        prepared.exif_focal_length_px.value_or(options_.unknown_focal_factor *
                                               std::max(width, height)),
        width, height);
  }
  const camera_t camera_id = reconstruction_.AddCamera(camera);
  camera_by_identity_[key] = camera_id;
  if (!known_camera_ && options_.self_calibration_growth > 0) {
    self_calibrating_[camera_id] = 0;
  }
  return camera_id;
}

void Engine::VerifyPairs(image_t image_id, const std::vector<RetrievalCandidate>& candidates,
                         ImageResult* result) {
  // Until the model exists every candidate is matched: initialisation needs
  // the wide-baseline pairs, which rank low in retrieval.
  std::vector<char> lsm_refined(features_.at(image_id).size(), 0);
  const FeatureDescriptors root_sift = RootSift(features_.at(image_id).descriptors);
  // Past the limit, the candidates of the sub-models the shot has no
  // verified pair in: the evidence that links two (SubModelOptions).
  std::set<model_t> verified_in;
  std::map<model_t, int> link_tries;
  for (const RetrievalCandidate& candidate : candidates) {
    const image_t other_id = candidate.image_id;
    const model_t other_model = reconstruction_.image(other_id).model_id;
    if (initialized_ && result->num_verified_pairs >= options_.max_verified_pairs) {
      if (!options_.sub_models.enabled || other_model == kInvalidModelId ||
          verified_in.count(other_model) ||
          link_tries[other_model]++ >= options_.sub_models.link_candidates) {
        continue;
      }
    }
    refinement_.tried_pairs.insert(ImagePairKey(image_id, other_id));
    PairVerification pair =
        verifier_.Verify(image_id, features_.at(image_id), root_sift, other_id,
                         features_.at(other_id), lsm_refined, &result->times);
    Image& image = reconstruction_.image(image_id);
    for (const auto& [point2D_idx, xy] : pair.refined) {
      image.points2D[point2D_idx].xy = xy;
      lsm_refined[point2D_idx] = 1;
    }
    result->num_lsm_rejected += pair.num_lsm_rejected;
    if (!pair.verified()) continue;
    ++result->num_verified_pairs;
    if (other_model != kInvalidModelId) verified_in.insert(other_model);
    // Once the model exists, a pair of waiting images may start a sub-model.
    if (!initialized_ ||
        (options_.sub_models.enabled && !reconstruction_.image(other_id).IsRegistered())) {
      initializer_.AddPair(image_id, other_id, pair.geometry, known_camera_.has_value());
    }
    matches_.SetMatches(image_id, other_id, std::move(pair.matches));
  }
}

bool Engine::Initialize(ImageResult* result, image_t image_id) {
  std::vector<InitialPair> pairs;
  {
    ScopedStageTimer timer(&result->times.registration);
    if (initialized_) initializer_.ForgetRegistered(reconstruction_);
    // A guessed focal length far off distorts every pose E gives (fountain-
    // P11 from a guess 2.8 times too long: 44 mm instead of 2 mm): the one
    // the pairs' F agree on replaces it, and the poses follow. Not for a
    // sub-model: the model's images hold the focal length to their poses.
    bool corrected = false;
    for (const auto& [camera_id, calm] : self_calibrating_) {
      if (initialized_) break;
      double focal_length = 0;
      if (initializer_.CorrectFocalLength(reconstruction_, camera_id, &focal_length) == 1) {
        reconstruction_.camera(camera_id).SetFocalLength(focal_length);
        result->focal_length_from_pairs = focal_length;
        corrected = true;
      }
    }
    if (corrected) {
      reconstruction_.MarkCamerasChanged();
      initializer_.RecomputePoses(reconstruction_, matches_);
    }
    pairs = initializer_.RankPairs(reconstruction_, matches_, image_id);
  }
  const model_t model_id =
      initialized_ ? reconstruction_.NewModelId() : Reconstruction::kFirstModelId;
  for (const InitialPair& pair : pairs) {
    // A pair that fails must leave no trace, its BA's intrinsics included:
    // every image of the same size shares the camera.
    const std::map<camera_t, Camera> cameras = reconstruction_.cameras();
    {
      ScopedStageTimer timer(&result->times.registration);
      reconstruction_.RegisterImage(pair.image_id1, Rigid3d(), model_id);
      reconstruction_.RegisterImage(pair.image_id2, pair.cam2_from_cam1, model_id);
    }
    TriangulateAndAdjust(pair.image_id2, result);
    if (reconstruction_.image(pair.image_id2).num_points3D >=
        options_.initialization.min_num_points) {
      initialized_ = true;
      if (options_.sub_models.enabled) {
        initializer_.ForgetRegistered(reconstruction_);
      } else {
        initializer_.Clear();
      }
      return true;
    }
    ScopedStageTimer timer(&result->times.registration);
    reconstruction_.DeRegisterImage(pair.image_id1);
    reconstruction_.DeRegisterImage(pair.image_id2);
    for (const auto& [camera_id, camera] : cameras) reconstruction_.camera(camera_id) = camera;
    reconstruction_.MarkCamerasChanged();
    initializer_.Discard(pair);
  }
  return false;
}

bool Engine::RegisterAndExtend(image_t image_id, ImageResult* result) {
  const Registrar::Result registered = registrar_.Register(image_id, &result->times);
  result->num_correspondences = registered.num_correspondences;
  result->num_densified = registered.num_densified;
  result->num_pose_inliers = registered.num_pose_inliers;
  if (!registered.success) {
    result->reason = registered.reason;
    return false;
  }
  TriangulateAndAdjust(image_id, result);
  LinkSubModels(image_id, result);
  return true;
}

void Engine::LinkSubModels(image_t image_id, ImageResult* result) {
  const auto reaches_another = [&] {
    const model_t own_id = reconstruction_.image(image_id).model_id;
    const std::vector<image_t> neighbours = matches_.Neighbours(image_id);
    return std::any_of(neighbours.begin(), neighbours.end(), [&](image_t other_id) {
      const Image& other = reconstruction_.image(other_id);
      return other.IsRegistered() && other.model_id != own_id;
    });
  };
  if (!options_.sub_models.enabled || !reaches_another()) return;
  ScopedStageTimer timer(&result->times.merge);
  // Each merge changes the correspondences: they are found again.
  for (bool merged = true; merged;) {
    merged = false;
    const model_t own_id = reconstruction_.image(image_id).model_id;
    const std::map<model_t, std::vector<Correspondence2D3D>> per_model =
        Find2D3DCorrespondences(reconstruction_, matches_, image_id);
    for (const auto& [other_id, correspondences] : per_model) {
      if (other_id == own_id) continue;
      std::optional<SubModelView> view = PoseInSubModel(
          reconstruction_, image_id, other_id, correspondences, options_.sub_models);
      if (!view) continue;
      const auto own = per_model.find(own_id);
      if (own != per_model.end()) {
        view->registered_matches =
            RegisteredMatches(reconstruction_, image_id, own->second, options_.sub_models);
      }
      for (const image_t neighbour : matches_.Neighbours(image_id)) {
        const Image& image = reconstruction_.image(neighbour);
        if (!image.IsRegistered()) continue;
        if (image.model_id == own_id) view->registered_neighbours.push_back(neighbour);
        if (image.model_id == other_id) view->posed_neighbours.push_back(neighbour);
      }
      ++result->num_posed_in_others;
      // The evidence of earlier shots between the two stays while their
      // shots stay where they registered.
      const std::pair<model_t, model_t> key = std::minmax(own_id, other_id);
      std::vector<SubModelView>& views = link_views_[key];
      views.erase(std::remove_if(views.begin(), views.end(),
                                 [&](const SubModelView& earlier) {
                                   const Image& shot = reconstruction_.image(earlier.image_id);
                                   return earlier.image_id == image_id ||
                                          shot.model_id != earlier.registered_in;
                                 }),
                  views.end());
      views.insert(views.begin(), std::move(*view));
      const std::optional<SubModelLink> link =
          FindSubModelLink(reconstruction_, views, options_.sub_models);
      if (!link) continue;
      const SubModelMerge merge = MergeSubModels(*link, &reconstruction_);
      const model_t gone = merge.model_id == own_id ? other_id : own_id;
      for (auto it = link_views_.begin(); it != link_views_.end();) {
        it = it->first.first == gone || it->first.second == gone ? link_views_.erase(it)
                                                                 : std::next(it);
      }
      reconstruction_.FilterPoints3D(merge.fused_points, options_.filter_max_error_px,
                                     options_.filter_min_tri_angle_deg);
      ++result->num_merged_models;
      merged = true;
      break;
    }
  }
  if (result->num_merged_models == 0) return;
  // The seam: the shot's tracks continue into the merged images, and the
  // local BA settles them; refinement's global BA follows between shots.
  // Its stage times lie in the merge's.
  ImageResult seam;
  TriangulateAndAdjust(image_id, &seam);
  result->num_merged_points += seam.num_merged_points;
  refinement_.adjust = true;
}

void Engine::TriangulateAndAdjust(image_t image_id, ImageResult* result) {
  // 8. Triangulation, with track continuation, completion and merging.
  {
    ScopedStageTimer timer(&result->times.triangulation);
    const Triangulator::Summary summary = triangulator_.TriangulateImage(image_id);
    result->num_new_points += summary.num_new_points;
    result->num_merged_points += summary.num_merged;
    result->num_completed += summary.num_continued + summary.num_completed;
  }

  // 9. Hierarchical weighted local BA over the association tree; 10. filter.
  ScopedStageTimer timer(&result->times.ba);
  HierarchicalAssociationTree::Options tree_options = options_.ba_tree;
  if (!options_.hierarchical_weights) {
    tree_options.k = 1.0;
    tree_options.fix_outermost_ripple = false;
  }
  const HierarchicalAssociationTree tree = HierarchicalAssociationTree::Build(
      int(image_id),
      [&](int id) { return RetrievalNeighbours(image_t(id), tree_options.top_n); },
      tree_options);
  std::unordered_map<image_t, double> weights;
  for (const auto& ripple : tree.ripples()) {
    for (const int id : ripple) weights[image_t(id)] = tree.WeightOf(id);
  }
  const SceneBundleResult adjusted = AdjustLocalBundle(
      weights, options_.local_ba, options_.ba_max_constant_observers, &reconstruction_);
  result->ba_free_images = adjusted.summary.num_free_images;
  result->ba_images = adjusted.summary.num_images;
  result->ba_points = adjusted.summary.num_points;
  result->ba_iterations = adjusted.summary.num_iterations;
  reconstruction_.FilterPoints3D(adjusted.points, options_.filter_max_error_px,
                                 options_.filter_min_tri_angle_deg);
  // 10b. While guessed intrinsics converge, the whole model follows them.
  AdjustWhileSelfCalibrating(result);
}

void Engine::AdjustWhileSelfCalibrating(ImageResult* result) {
  const std::size_t num_images = reconstruction_.NumRegisteredImages();
  if (self_calibrating_.empty() || num_images < next_self_calibration_images_) return;
  next_self_calibration_images_ = std::max(
      num_images + 1,
      std::size_t(std::ceil(double(num_images) * options_.self_calibration_growth)));
  const std::map<camera_t, Camera> before = reconstruction_.cameras();
  BundleAdjuster::Options options = options_.global_ba;
  const double share = double(options_.self_calibration_max_observations) /
                       double(std::max<std::size_t>(reconstruction_.NumObservations(), 1));
  if (share < 1) {
    options.max_num_iterations =
        std::max(options_.self_calibration_min_iterations,
                 int(std::floor(share * double(options.max_num_iterations))));
  }
  const BundleAdjuster::Summary summary = AdjustGlobalBundle(options, &reconstruction_).summary;
  reconstruction_.FilterAllPoints3D(options_.filter_max_error_px,
                                    options_.filter_min_tri_angle_deg);
  result->global_ba = true;
  result->global_ba_iterations = summary.num_iterations;
  // A BA stopped by its iteration limit may have moved the focal length
  // little only because it was cut short.
  const bool converged = summary.termination == BundleAdjuster::Termination::kConvergence;
  constexpr int kCalmAdjustments = 3;
  for (auto it = self_calibrating_.begin(); it != self_calibrating_.end();) {
    auto& [camera_id, calm] = *it;
    const double change = std::abs(reconstruction_.camera(camera_id).MeanFocalLength() /
                                       before.at(camera_id).MeanFocalLength() -
                                   1);
    calm = converged && change < options_.self_calibration_converged_change ? calm + 1 : 0;
    it = calm >= kCalmAdjustments ? self_calibrating_.erase(it) : std::next(it);
  }
}

void Engine::RetryPending(std::vector<ImageResult>* results) {
  // Images registered already (the new one, or an initial pair) leave first.
  for (const image_t image_id : pending_.Images()) {
    if (!reconstruction_.image(image_id).IsRegistered()) continue;
    pending_.Remove(image_id);
    if (image_id != (*results)[0].image_id) results->push_back(ResultFor(image_id));
  }
  if (!initialized_) return;
  const auto count = [this](image_t id) { return NumRegisteredNeighbours(id); };
  for (image_t image_id; (image_id = pending_.NextDue(count)) != kInvalidImageId;) {
    pending_.MarkTried(image_id, count(image_id));
    ImageResult attempt = ResultFor(image_id);
    const bool registered = RegisterAndExtend(image_id, &attempt);
    if (!registered) {
      // A failed try is work done for the new image's call.
      attempt.times.UpdateTotal();
      (*results)[0].times.pending += attempt.times.total;
      continue;
    }
    pending_.Remove(image_id);
    if (image_id == (*results)[0].image_id) {
      ImageResult& own = (*results)[0];
      AddTimes(attempt.times, &own.times);
      attempt.times = own.times;
      attempt.num_features = own.num_features;
      attempt.num_candidates = own.num_candidates;
      attempt.num_verified_pairs = own.num_verified_pairs;
      attempt.num_lsm_rejected = own.num_lsm_rejected;
      own = std::move(attempt);
    } else {
      results->push_back(std::move(attempt));
    }
  }
}

void Engine::KeepLsmWindows() {
  const auto keep_windows = [this](image_t image_id) {
    std::vector<Eigen::Vector2d> points;
    for (const Point2D& point2D : reconstruction_.image(image_id).points2D) {
      points.push_back(point2D.xy);
    }
    lsm_images_.KeepWindows(image_id, points);
  };
  std::vector<image_t> waiting;
  for (const image_t image_id : lsm_images_.WholeImages()) {
    if (reconstruction_.image(image_id).IsRegistered()) {
      keep_windows(image_id);
    } else {
      waiting.push_back(image_id);
    }
  }
  // The most recent waiting images stay whole, to be searched when they are
  // tried again.
  const int num_whole = options_.lsm_images.max_whole_waiting_images;
  for (int i = 0; i + num_whole < int(waiting.size()); ++i) keep_windows(waiting[i]);
}

int Engine::NumRegisteredNeighbours(image_t image_id) const {
  int count = 0;
  for (const image_t other_id : matches_.Neighbours(image_id)) {
    count += reconstruction_.image(other_id).IsRegistered();
  }
  return count;
}

std::vector<int> Engine::RetrievalNeighbours(image_t image_id, int n) const {
  std::vector<int> neighbours;
  // Pending images are interleaved in the ranking: ask for more.
  // A local BA stays in the image's sub-model.
  const model_t model_id = reconstruction_.image(image_id).model_id;
  for (const RetrievalCandidate& candidate : retriever_.QueryInserted(image_id, 3 * n)) {
    const Image& candidate_image = reconstruction_.image(candidate.image_id);
    if (candidate_image.IsRegistered() && candidate_image.model_id == model_id) {
      neighbours.push_back(int(candidate.image_id));
      if (int(neighbours.size()) == n) break;
    }
  }
  return neighbours;
}

ImageResult Engine::ResultFor(image_t image_id) const {
  ImageResult result;
  result.image_id = image_id;
  result.name = reconstruction_.image(image_id).name;
  return result;
}

const char* Engine::FinishStepName(FinishProgress::Step step) {
  switch (step) {
    case FinishProgress::Step::kRetry: return "waiting images tried again";
    case FinishProgress::Step::kAdjust: return "global adjustment";
    case FinishProgress::Step::kSnoop: return "data snooping";
  }
  return "";
}

std::vector<ImageResult> Engine::Finish(
    const std::function<void(const FinishProgress&)>& progress) {
  const auto start = std::chrono::steady_clock::now();
  FinishProgress state;
  const auto tell = [&] {
    if (!progress) return;
    state.elapsed_s =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    progress(state);
  };
  tell();
  pending_.ForgetTries();
  std::vector<ImageResult> results = RetryWaiting();
  for (ImageResult& result : results) Finalize(&result);
  if (options_.final_global_ba && reconstruction_.NumRegisteredImages() >= 2 &&
      !RefinedToTheEnd()) {
    BundleAdjuster::Options options = options_.global_ba;
    options.num_threads = options_.finishing.num_threads;
    options.function_tolerance =
        std::max(options.function_tolerance, options_.finishing.function_tolerance);
    // One budget of time for the global BA and the snooping's.
    const double budget_s = std::max(options_.finishing.min_seconds,
                                     options_.finishing.max_share_of_run * work_seconds_);
    // Counted from Finish's start, the retries included.
    const auto spent_s = [&] {
      return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    };
    // An iteration costs about what the last one did: none starts that
    // would end past the budget, so the budget bounds the end rather than
    // being overrun by one iteration.
    double last_iteration_end_s = spent_s();
    double iteration_s = 0;
    options.on_iteration = [&](int iteration) {
      if (iteration == 0 && state.step == FinishProgress::Step::kSnoop) ++state.round;
      const double now_s = spent_s();
      // A round's iteration 0 ends the snooping's work between rounds, no
      // iteration: the last cost stands.
      if (iteration > 0) iteration_s = now_s - last_iteration_end_s;
      last_iteration_end_s = now_s;
      state.iteration = iteration;
      state.max_iterations = options.max_num_iterations;
      state.remaining_s = std::max(0.0, budget_s - now_s);
      tell();
    };
    options.should_stop = [&] { return spent_s() + iteration_s >= budget_s; };
    state.step = FinishProgress::Step::kAdjust;
    AdjustGlobalBundle(options, &reconstruction_);
    reconstruction_.FilterAllPoints3D(options_.filter_max_error_px,
                                      options_.filter_min_tri_angle_deg);
    if (options_.outlier_quantile > 0 && spent_s() < budget_s) {
      state.step = FinishProgress::Step::kSnoop;
      state.max_rounds = options_.outlier_max_rounds;
      SnoopOutliers(options_.outlier_quantile, options_.outlier_max_rounds, options,
                    options_.filter_min_tri_angle_deg, &reconstruction_);
    }
  }
  reconstruction_.UpdatePointErrors();
  return results;
}

bool Engine::RefinedToTheEnd() const {
  const RefinementState& state = refinement_;
  return options_.refinement.enabled && state.snooped_everything && !state.adjust &&
         state.to_match.empty() && state.to_triangulate.empty() &&
         state.to_retriangulate.empty() && !state.snoop;
}

bool Engine::HasImageFile(image_t image_id) const {
  const auto file = image_files_.find(image_id);
  return file != image_files_.end() && !file->second.empty();
}

std::vector<std::string> Engine::PendingImageNames() const {
  std::vector<std::string> names;
  for (const image_t id : pending_.Images()) names.push_back(reconstruction_.image(id).name);
  return names;
}

void Engine::Finalize(ImageResult* result) const {
  result->times.UpdateTotal();
  result->model_images = int(reconstruction_.NumRegisteredImages());
  result->model_points = int(reconstruction_.NumPoints3D());
  result->num_models = int(reconstruction_.Models().size());
  if (result->image_id == kInvalidImageId) return;
  const Image& image = reconstruction_.image(result->image_id);
  if (image.IsRegistered()) {
    result->status = ImageStatus::kRegistered;
    result->reason.clear();
    result->cam_from_world = image.cam_from_world;
    result->model_id = image.model_id;
    result->num_observations = image.num_points3D;
  }
}

}  // namespace flysfm
