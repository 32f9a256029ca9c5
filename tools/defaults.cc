#include "tools/defaults.h"

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <functional>
#include <map>
#include <optional>
#include <regex>
#include <set>
#include <sstream>
#include <type_traits>

#include "core/engine.h"
#include "geometry/camera.h"
#include "io/camfi/camfi_client.h"
#include "io/camfi/camfi_emulator.h"
#include "io/run/checkpoint.h"
#include "io/sources/merged_source.h"
#include "io/sources/watched_folder.h"
#include "io/synthetic/synthetic_source.h"
#include "io/view/view_server.h"
#include "quality/coverage.h"
#include "quality/quality_tracker.h"
#include "retrieval/retrieval_model.h"

namespace flysfm {
namespace {

using Out = std::vector<OptionDefault>;

// ---- Values, in the format OptionDefault documents ----

std::string Format(bool value) { return value ? "true" : "false"; }

template <typename T, std::enable_if_t<std::is_integral_v<T> && !std::is_same_v<T, bool>, int> = 0>
std::string Format(T value) {
  return std::to_string(value);
}

std::string Format(double value) {
  char text[64];
  std::snprintf(text, sizeof(text), "%.10g", value);
  return text;
}

// An empty string must still be visible in a table and quotable in a code
// span, hence the quotes.
std::string Format(const std::string& value) { return value.empty() ? "\"\"" : value; }

std::string Format(const std::filesystem::path& value) { return Format(value.string()); }

// A callback cannot be printed; whether the default sets one can.
template <typename R, typename... Args>
std::string Format(const std::function<R(Args...)>& value) {
  return value ? "set" : "none";
}

template <typename Container>
std::string FormatList(const Container& values, const char* separator) {
  if (values.empty()) return "none";
  std::string text;
  for (const auto& value : values) {
    if (!text.empty()) text += separator;
    text += Format(value);
  }
  return text;
}
template <typename T>
std::string Format(const std::vector<T>& values) {
  return FormatList(values, ", ");
}

// Enums: no default case, so that -Wswitch names a new enumerator here.
std::string Format(MatcherBackend value) {
  switch (value) {
    case MatcherBackend::kExact: return "exact";
    case MatcherBackend::kApproximate: return "approximate";
  }
  return "?";
}
std::string Format(LsmSolver value) {
  switch (value) {
    case LsmSolver::kGaussNewton: return "gauss-newton";
    case LsmSolver::kLevenbergMarquardt: return "levenberg-marquardt";
  }
  return "?";
}
std::string Format(LsmInterpolation value) {
  switch (value) {
    case LsmInterpolation::kBilinear: return "bilinear";
    case LsmInterpolation::kCubicSpline: return "cubic-spline";
  }
  return "?";
}
std::string Format(BundleAdjuster::Options::Loss value) {
  using Loss = BundleAdjuster::Options::Loss;
  switch (value) {
    case Loss::kTrivial: return "trivial";
    case Loss::kHuber: return "huber";
    case Loss::kCauchy: return "cauchy";
  }
  return "?";
}
std::string Format(BundleAdjuster::Options::Gauge value) {
  using Gauge = BundleAdjuster::Options::Gauge;
  switch (value) {
    case Gauge::kConstantPosesOnly: return "constant-poses-only";
    case Gauge::kMinimal: return "minimal";
  }
  return "?";
}
std::string Format(MergedSourceOptions::Order value) {
  using Order = MergedSourceOptions::Order;
  switch (value) {
    case Order::kArrival: return "arrival";
    case Order::kCaptureTime: return "capture-time";
    case Order::kRoundRobin: return "round-robin";
  }
  return "?";
}
std::string Format(QualityTracker::Options::Sigma value) { return SigmaSourceName(value); }
std::string Format(CameraModelId value) { return CameraModelName(value); }
std::string Format(const std::set<CamfiFault>& faults) {
  std::vector<std::string> names;
  for (const CamfiFault fault : faults) names.push_back(CamfiFaultName(fault));
  return FormatList(names, ", ");
}

// Replaces the help of every entry listed since `first` whose key starts
// with `prefix`: a nested struct whose member means something else where it
// is nested (a RANSAC threshold its owner overrides).
void Rehelp(Out* out, std::size_t first, const std::string& prefix, const std::string& help,
            bool prepend) {
  for (std::size_t i = first; i < out->size(); ++i) {
    OptionDefault& entry = (*out)[i];
    if (entry.key.compare(0, prefix.size(), prefix) != 0) continue;
    entry.help = prepend ? help + entry.help : help;
  }
}

// ---- One List per options struct ----
//
// The key is spelt by the member's own name and the value read from the
// default-constructed struct `o`, so neither can drift from the code. Each
// List starts with a structured binding naming every data member: it does
// not compile when the struct gains or loses one, so a new option cannot be
// left out of this page. Adding an option: its name in the binding and one
// OPTION line (or NESTED, for a struct) in declaration order.
#define OPTION(member, help) out->push_back({prefix + #member, Format(o.member), help})
#define NESTED(member) List(prefix + #member ".", o.member, out)

void List(const std::string& prefix, const DecodeOptions& o, Out* out) {
  [[maybe_unused]] const auto& [max_image_pixels, max_file_bytes] = o;
  OPTION(max_image_pixels, "An image whose header claims more pixels is rejected before decoding");
  OPTION(max_file_bytes, "A larger file (bytes) is not read");
}

void List(const std::string& prefix, const SiftOptions& o, Out* out) {
  [[maybe_unused]] const auto& [max_num_features, large_scale_share, max_image_size,
                                peak_threshold, edge_threshold, num_octave_layers] = o;
  OPTION(max_num_features, "SIFT features kept per image");
  OPTION(large_scale_share,
         "Share of the kept features chosen by largest scale, the rest by strongest response");
  OPTION(max_image_size, "Longest image side used for extraction (px); larger images are downscaled");
  OPTION(peak_threshold, "OpenCV SIFT's contrast threshold on the DoG peaks");
  OPTION(edge_threshold, "Ratio of principal curvatures above which edge responses are rejected");
  OPTION(num_octave_layers, "Scale levels per octave");
}

void List(const std::string& prefix, const VocabularyTreeIndexOptions& o, Out* out) {
  [[maybe_unused]] const auto& [candidate_factor, min_candidates] = o;
  OPTION(candidate_factor, "A query ranks at least this many times N images of the nearest leaves");
  OPTION(min_candidates, "... and at least this many");
}

void List(const std::string& prefix, const VladOptions& o, Out* out) {
  [[maybe_unused]] const auto& [num_words, pca_dim, power, whitening_regularisation,
                                min_pca_samples, max_training_descriptors, kmeans_iterations,
                                crops_per_image, min_crop_features, seed] = o;
  OPTION(num_words, "VLAD codebook size");
  OPTION(pca_dim, "Descriptor dimension after PCA-whitening");
  OPTION(power, "Exponent of the signed power normalisation (damps bursty words)");
  OPTION(whitening_regularisation, "Whitening regulariser: damps low-variance directions");
  OPTION(min_pca_samples, "Training vectors PCA needs; with fewer, the raw VLAD is used");
  OPTION(max_training_descriptors, "Random descriptors the codebook is learnt on");
  OPTION(kmeans_iterations, "Lloyd iterations of the codebook's k-means");
  OPTION(crops_per_image, "Random crops per training image, each giving a training VLAD");
  OPTION(min_crop_features, "Crops with fewer keypoints are not used");
  OPTION(seed, "Random seed");
}

void List(const std::string& prefix, const VocabularyTreeOptions& o, Out* out) {
  [[maybe_unused]] const auto& [branching, depth, kmeans_iterations, seed] = o;
  OPTION(branching, "Vocabulary tree: children per node");
  OPTION(depth, "Vocabulary tree: levels");
  OPTION(kmeans_iterations, "Lloyd iterations of each node's k-means");
  OPTION(seed, "Random seed");
}

void List(const std::string& prefix, const RetrievalTrainingOptions& o, Out* out) {
  [[maybe_unused]] const auto& [sift, vlad, tree] = o;
  NESTED(sift);
  NESTED(vlad);
  NESTED(tree);
}

void List(const std::string& prefix, const ImageRetrieverOptions& o, Out* out) {
  [[maybe_unused]] const auto& [num_candidates, use_tree, tree_index, training,
                                bootstrap_freeze_images, min_tree_images] = o;
  OPTION(num_candidates, "Candidates per retrieval query (the paper's top-N)");
  OPTION(use_tree, "Vocabulary tree index; false: an exhaustive index throughout");
  NESTED(tree_index);
  const std::size_t first = out->size();
  NESTED(training);
  Rehelp(out, first, prefix + "training.sift.",
         "Not used (the engine's own features come in); ", /*prepend=*/true);
  OPTION(bootstrap_freeze_images,
         "Bootstrapped retrieval: the VLAD model is frozen once trained on this many images");
  OPTION(min_tree_images, "Below this many images the index is exhaustive");
}

// `owner_threshold`: the owner's own max_error_px replaces max_error.
void List(const std::string& prefix, const RansacOptions& o, Out* out,
          bool owner_threshold = false) {
  [[maybe_unused]] const auto& [max_error, confidence, min_iterations, max_iterations,
                                min_inlier_ratio, local_optimization, lo_max_iterations,
                                final_refinement, max_refinements, seed] = o;
  OPTION(max_error, owner_threshold ? "Not used: max_error_px above is the threshold"
                                    : "Inlier threshold on the error, in the estimator's units");
  OPTION(confidence, "Stop once an all-inlier sample was drawn with this probability");
  OPTION(min_iterations, "Samples drawn at least");
  OPTION(max_iterations, "Samples drawn at most");
  OPTION(min_inlier_ratio,
         "Never sample longer than finding a model with this inlier ratio takes (0: no bound)");
  OPTION(local_optimization, "LO-RANSAC: least squares on the inliers of each new best model");
  OPTION(lo_max_iterations, "Least-squares rounds per new best model");
  OPTION(final_refinement, "Refine on the final inliers while that improves the score");
  OPTION(max_refinements, "Final refinements at most");
  OPTION(seed, "Sampler seed: equal seeds and data give equal results");
}

void List(const std::string& prefix, const MatchOptions& o, Out* out) {
  [[maybe_unused]] const auto& [backend, max_ratio, mutual, max_distance, flann_num_trees,
                                flann_num_checks] = o;
  OPTION(backend, "Matcher: exact (brute force) or approximate (FLANN kd-trees)");
  OPTION(max_ratio, "Lowe's ratio test: nearest over second-nearest distance below this");
  OPTION(mutual, "Keep only mutual nearest neighbours");
  OPTION(max_distance, "Larger descriptor distances are dropped (RootSIFT's maximum: no bound)");
  OPTION(flann_num_trees, "Approximate matcher: randomised kd-trees");
  OPTION(flann_num_checks, "Approximate matcher: leaves checked per query");
}

void List(const std::string& prefix, const TwoViewGeometryOptions& o, Out* out) {
  [[maybe_unused]] const auto& [min_num_inliers_f, min_num_inliers_h, max_error_px,
                                min_gric_sigma_px, panoramic_min_inlier_ratio,
                                compute_relative_pose, ransac] = o;
  OPTION(min_num_inliers_f, "N_f: inliers F (or E) needs to verify the pair");
  OPTION(min_num_inliers_h, "N_h: inliers H needs to be a candidate");
  OPTION(max_error_px, "Inlier threshold of F, E and H: Sampson distance (px)");
  OPTION(min_gric_sigma_px, "Floor of GRIC's noise sigma (px)");
  OPTION(panoramic_min_inlier_ratio,
         "Known cameras: a pure rotation when a rotation-only H keeps this share of H's inliers");
  OPTION(compute_relative_pose, "Known cameras: recover the pair's relative pose");
  List(prefix + "ransac.", o.ransac, out, /*owner_threshold=*/true);
}

void List(const std::string& prefix, const LsmOptions& o, Out* out) {
  [[maybe_unused]] const auto& [window_size, solver, interpolation, convergence_shift_px,
                                convergence_corner_px, max_iterations, max_shift_px, min_ncc,
                                min_gradient, min_stddev, max_condition_number,
                                max_affine_scale] = o;
  OPTION(window_size, "Side of the square LSM window (px, odd)");
  OPTION(solver, "Gauss-Newton or (damped) Levenberg-Marquardt steps");
  OPTION(interpolation, "Image interpolation: bilinear or cubic-spline");
  OPTION(convergence_shift_px, "Converged once an update moves the point less than this (px)");
  OPTION(convergence_corner_px, "... and every corner of the window less than this (px)");
  OPTION(max_iterations, "Iterations at most");
  OPTION(max_shift_px, "Largest final distance of the refined position from the start (px)");
  OPTION(min_ncc, "Least normalised cross-correlation of template and warped window");
  OPTION(min_gradient,
         "Least RMS grey-level gradient along the template's weakest direction (per px)");
  OPTION(min_stddev, "Least grey-level standard deviation of either window");
  OPTION(max_condition_number, "Largest condition number of the scaled normal matrix");
  OPTION(max_affine_scale, "Largest stretch of the window by its affine part, either way");
}

void List(const std::string& prefix, const PairVerifier::Options& o, Out* out) {
  [[maybe_unused]] const auto& [matching, two_view, lsm_refinement, lsm] = o;
  NESTED(matching);
  NESTED(two_view);
  OPTION(lsm_refinement, "The paper's LSM refinement of verified matches; off only for ablation");
  NESTED(lsm);
}

void List(const std::string& prefix, const LsmImageStore::Options& o, Out* out) {
  [[maybe_unused]] const auto& [num_pyramid_levels, template_reach_px, coarse_template_reach_px,
                                window_budget_megabytes, max_whole_waiting_images] = o;
  OPTION(num_pyramid_levels, "Pyramid levels kept per image");
  OPTION(template_reach_px, "Pixels kept around each 2D point of an older image, level 0");
  OPTION(coarse_template_reach_px, "The same on the coarser levels");
  OPTION(window_budget_megabytes, "Budget of the tiles kept of older images (MB)");
  OPTION(max_whole_waiting_images, "Waiting images kept whole beyond the new one");
}

void List(const std::string& prefix, const FocalFromFundamentalOptions& o, Out* out) {
  [[maybe_unused]] const auto& [min_focal_length_factor, max_focal_length_factor, num_samples,
                                min_contrast, min_gap_rise] = o;
  OPTION(min_focal_length_factor, "Focal lengths searched from this times the longer image side");
  OPTION(max_focal_length_factor, "... to this times it");
  OPTION(num_samples, "Focal lengths sampled (geometrically)");
  OPTION(min_contrast, "Replace the reference only when its gap is this many times the minimum's");
  OPTION(min_gap_rise, "... and more than this above it");
}

void List(const std::string& prefix, const Initializer::Options& o, Out* out) {
  [[maybe_unused]] const auto& [min_num_inliers, min_tri_angle_deg, min_num_points,
                                min_point_angle_deg, max_error_px, focal_from_fundamental] = o;
  OPTION(min_num_inliers, "Verified matches a pair needs to start the model");
  OPTION(min_tri_angle_deg, "Least median triangulation angle of its points (deg)");
  OPTION(min_num_points, "Least well-triangulated points");
  OPTION(min_point_angle_deg, "A point counts when seen under this angle (deg)");
  OPTION(max_error_px, "... and reprojected within this in both images (px)");
  NESTED(focal_from_fundamental);
}

void List(const std::string& prefix, const AbsolutePoseOptions& o, Out* out) {
  [[maybe_unused]] const auto& [max_error_px, min_num_inliers, refine, ransac] = o;
  OPTION(max_error_px, "Inlier threshold on the reprojection error (px)");
  OPTION(min_num_inliers, "Inliers a pose needs");
  OPTION(refine, "Levenberg-Marquardt refinement of the final pose on its inliers");
  List(prefix + "ransac.", o.ransac, out, /*owner_threshold=*/true);
}

void List(const std::string& prefix, const DensifyOptions& o, Out* out) {
  [[maybe_unused]] const auto& [lsm, num_pyramid_levels, max_displacement_px, predict_affine,
                                max_references_per_point, window_shift_px, max_relative_sigma0,
                                min_depth] = o;
  NESTED(lsm);
  OPTION(num_pyramid_levels, "Coarse-to-fine levels correcting the first pose (1: none)");
  OPTION(max_displacement_px, "Largest distance of an accepted position from the reprojection (px)");
  OPTION(predict_affine, "Start the window's shape from a fronto-parallel plane's map");
  OPTION(max_references_per_point, "Reference observations tried per point at full resolution");
  OPTION(window_shift_px, "Shift of the windows tried when no centred one is accepted (px; 0: none)");
  OPTION(max_relative_sigma0, "A window is accepted with at most this times the median sigma0");
  OPTION(min_depth, "Least depth in front of the new camera, relative to the distance");
}

void List(const std::string& prefix, const Registrar::Options& o, Out* out) {
  [[maybe_unused]] const auto& [min_num_correspondences, absolute_pose, lsm_densification,
                                densify, densify_max_references, densify_max_candidates] = o;
  OPTION(min_num_correspondences, "2D-3D correspondences needed to try a pose");
  NESTED(absolute_pose);
  OPTION(lsm_densification, "The paper's LSM densification; off only for ablation");
  NESTED(densify);
  OPTION(densify_max_references, "Registered neighbours whose points densification projects");
  OPTION(densify_max_candidates, "Points tried per image at most, longest tracks first");
}

void List(const std::string& prefix, const TriangulationOptions& o, Out* out) {
  [[maybe_unused]] const auto& [max_error_px, min_tri_angle_deg, min_num_inliers, refine,
                                ransac] = o;
  OPTION(max_error_px, "An observation is an inlier when the point reprojects within this (px)");
  OPTION(min_tri_angle_deg, "Least angle between two rays of every sample and inlier set (deg)");
  OPTION(min_num_inliers, "Least inlier observations");
  OPTION(refine, "Gauss-Newton refinement of the point on its inliers");
  List(prefix + "ransac.", o.ransac, out, /*owner_threshold=*/true);
}

void List(const std::string& prefix, const Triangulator::Options& o, Out* out) {
  [[maybe_unused]] const auto& [triangulation, complete_and_merge_tracks] = o;
  NESTED(triangulation);
  OPTION(complete_and_merge_tracks, "Complete and merge the tracks the image observes");
}

void List(const std::string& prefix, const HierarchicalAssociationTree::Options& o, Out* out) {
  [[maybe_unused]] const auto& [top_n, depth, k, fix_outermost_ripple] = o;
  OPTION(top_n, "Neighbours taken from each image's retrieval list");
  OPTION(depth, "Ripples L of the association tree");
  OPTION(k, "Ratio of the weights of successive ripples");
  OPTION(fix_outermost_ripple, "Hold the outermost ripple fixed");
}

void List(const std::string& prefix, const BundleAdjuster::Options& o, Out* out) {
  [[maybe_unused]] const auto& [loss, loss_scale_px, refine_focal_length, refine_principal_point,
                                refine_extra_params, max_focal_length_change,
                                max_principal_point_offset, refine_readout_time,
                                max_readout_time_seconds, gauge, iterative_schur_min_track_length,
                                dense_schur_max_images, sparse_schur_max_images,
                                max_num_iterations, max_solver_time_seconds, function_tolerance,
                                gradient_tolerance, parameter_tolerance, num_threads,
                                should_stop, on_iteration] = o;
  OPTION(loss, "Robust loss: trivial, huber or cauchy");
  OPTION(loss_scale_px, "Scale of the robust loss (px)");
  OPTION(refine_focal_length, "Refine every camera's focal length");
  OPTION(refine_principal_point, "Refine every camera's principal point");
  OPTION(refine_extra_params, "Refine every camera's distortion parameters");
  OPTION(max_focal_length_change, "A refined focal length stays within this factor of its start");
  OPTION(max_principal_point_offset,
         "A refined principal point stays within this share of the image size of its centre");
  OPTION(refine_readout_time, "Estimate the rolling-shutter readout time of moving images");
  OPTION(max_readout_time_seconds, "Bound on the readout time either way (s)");
  OPTION(gauge, "What holds a free block's similarity gauge");
  OPTION(iterative_schur_min_track_length,
         "Iterative Schur beyond this observation-weighted mean track length");
  OPTION(dense_schur_max_images, "Else dense Schur up to this many refined poses");
  OPTION(sparse_schur_max_images, "... sparse Schur up to this many, iterative beyond");
  OPTION(max_num_iterations, "Solver iterations at most");
  OPTION(max_solver_time_seconds, "Solver time at most (s)");
  OPTION(function_tolerance, "Ceres function tolerance");
  OPTION(gradient_tolerance, "Ceres gradient tolerance");
  OPTION(parameter_tolerance, "Ceres parameter tolerance");
  OPTION(num_threads, "Ceres threads");
  OPTION(should_stop, "Polled after each iteration to end the solve early (refinement sets it)");
  OPTION(on_iteration, "Told each iteration, for a progress line (the end of a run sets it)");
}

void List(const std::string& prefix, const Engine::Options::Refinement& o, Out* out) {
  [[maybe_unused]] const auto& [enabled, candidates_per_image, max_shared_points,
                                pairs_per_slice, images_per_slice, min_changed_observations,
                                max_adjustments, max_adjusted_observations] = o;
  OPTION(enabled, "Refine the model between shots");
  OPTION(candidates_per_image, "Retrieval candidates each image is matched with");
  OPTION(max_shared_points, "A pair whose images share this many points is not matched");
  OPTION(pairs_per_slice, "Pairs verified per slice at most");
  OPTION(images_per_slice, "Images triangulated per slice at most");
  OPTION(min_changed_observations,
         "Another global BA while retriangulation changes more than this share of observations");
  OPTION(max_adjustments, "Global BAs in a row without a new image at most");
  OPTION(max_adjusted_observations, "Past this many observations BA refines only the latest images");
}

void List(const std::string& prefix, const SubModelOptions& o, Out* out) {
  [[maybe_unused]] const auto& [enabled, min_link_points, min_inlier_ratio,
                                max_relative_distance, min_reprojected_ratio,
                                max_reprojection_error_px, link_candidates, min_context_ratio,
                                context_max_angle_deg, context_max_distance_ratio,
                                absolute_pose] = o;
  OPTION(enabled, "A shot that fits no model starts a sub-model with a waiting shot");
  OPTION(min_link_points, "A link needs the shot's pose in the other sub-model from this many "
                          "points, and this many 3D-3D correspondences agreeing");
  OPTION(min_inlier_ratio, "... and this share of the 3D-3D correspondences agreeing");
  OPTION(max_relative_distance,
         "Agreement: within this share of the median depth (rotations: radians)");
  OPTION(min_reprojected_ratio,
         "Of the agreeing points, this share reprojecting in every image of their counterpart");
  OPTION(max_reprojection_error_px, "... within this many pixels");
  OPTION(link_candidates, "Past max_verified_pairs, candidates still verified per sub-model "
                          "the shot has no verified pair in");
  OPTION(min_context_ratio,
         "Of the points each shot's two poses say it should see, the share it matched in one "
         "sub-model at least this share of that in the other");
  OPTION(context_max_angle_deg,
         "... points its matched images show from within this angle of the shot's ray (deg)");
  OPTION(context_max_distance_ratio, "... and at a distance within this factor of the shot's");
  NESTED(absolute_pose);
}

void List(const std::string& prefix, const Engine::Options::Finishing& o, Out* out) {
  [[maybe_unused]] const auto& [num_threads, function_tolerance, max_share_of_run,
                                min_seconds] = o;
  OPTION(num_threads, "Threads of the end's adjustments");
  OPTION(function_tolerance, "An adjustment of the end stops below this relative cost decrease");
  OPTION(max_share_of_run, "The end's adjustments stop past this share of the engine's time");
  OPTION(min_seconds, "... or past this many seconds when that is more (s)");
}

void List(const std::string& prefix, const Engine::Options& o, Out* out) {
  [[maybe_unused]] const auto& [decode, sift, retrieval, verification, max_verified_pairs,
                                lsm_images, initialization, registration, triangulation, ba_tree,
                                hierarchical_weights, local_ba, ba_max_constant_observers,
                                final_global_ba, global_ba, outlier_quantile, outlier_max_rounds,
                                filter_max_error_px, filter_min_tri_angle_deg,
                                unknown_focal_factor, self_calibration_growth,
                                self_calibration_converged_change,
                                self_calibration_max_observations,
                                self_calibration_min_iterations, sub_models, refinement,
                                finishing] = o;
  NESTED(decode);
  NESTED(sift);
  NESTED(retrieval);
  NESTED(verification);
  OPTION(max_verified_pairs, "Once the model exists, candidates are matched until this many verify");
  NESTED(lsm_images);
  NESTED(initialization);
  NESTED(registration);
  NESTED(triangulation);
  NESTED(ba_tree);
  OPTION(hierarchical_weights, "Ripple weights in the local BA; false: a plain local BA (ablation)");
  NESTED(local_ba);
  OPTION(ba_max_constant_observers, "Per point, observations from constant images at most (0: all)");
  OPTION(final_global_ba, "Finish() runs a global BA over everything");
  NESTED(global_ba);
  OPTION(outlier_quantile,
         "Data snooping drops observations beyond this quantile of their image's noise (0: none)");
  OPTION(outlier_max_rounds, "Snooping's adjustments at most");
  OPTION(filter_max_error_px, "After each BA, observations farther from their projection go (px)");
  OPTION(filter_min_tri_angle_deg, "... then points seen under less than this angle (deg)");
  OPTION(unknown_focal_factor,
         "Unknown intrinsics without EXIF: focal length as this times the longer side");
  OPTION(self_calibration_growth,
         "Guessed intrinsics: a global BA each time the model grows by this factor (0: none)");
  OPTION(self_calibration_converged_change,
         "Calibrated once such BAs move the focal length less than this (relative)");
  OPTION(self_calibration_max_observations,
         "Past this many observations a scheduled BA gets proportionally fewer iterations");
  OPTION(self_calibration_min_iterations, "... but at least this many");
  NESTED(sub_models);
  NESTED(refinement);
  NESTED(finishing);
}

void List(const std::string& prefix, const Checkpointer::Options& o, Out* out) {
  [[maybe_unused]] const auto& [max_snapshot_share] = o;
  OPTION(max_snapshot_share, "Share of the engine's time the snapshots may take");
}

void List(const std::string& prefix, const CamfiOptions& o, Out* out) {
  [[maybe_unused]] const auto& [host, http_port, event_port, password, tether_on_connect,
                                reconcile_seconds, list_page, max_list_pages, fetch_existing,
                                extensions, ignore_paths, cache_prefix, cache_route, retries,
                                control_timeout, list_timeout, download_idle_seconds,
                                download_total_seconds, max_shot_bytes, max_body_bytes,
                                max_event_message_bytes, max_json_depth, backoff_min_seconds,
                                backoff_max_seconds, engine_io_version, ping_interval_override_ms,
                                ping_timeout_override_ms, store_write_fault] = o;
  OPTION(host, "Device address (AP mode)");
  OPTION(http_port, "REST port");
  OPTION(event_port, "Event channel port");
  OPTION(password, "Access password, user CamFi (empty: none)");
  OPTION(tether_on_connect, "POST /tether/start on every (re)connect");
  OPTION(reconcile_seconds, "List /files this often while live (s)");
  OPTION(list_page, "Page size of /files");
  OPTION(max_list_pages, "Pages of one listing at most");
  OPTION(fetch_existing, "Fetch the files already on the card when a fresh store starts");
  OPTION(extensions, "Extensions fetched (lower case); other files are skipped");
  OPTION(ignore_paths, "Placeholder paths some firmware announces");
  OPTION(cache_prefix, "Device paths under this prefix are served by cache_route");
  OPTION(cache_route, "Route of the paths under cache_prefix (others: /raw/)");
  OPTION(retries, "Download attempts per shot before it waits for the next listing");
  OPTION(control_timeout, "Timeout of control calls (s)");
  OPTION(list_timeout, "Timeout of a listing (s)");
  OPTION(download_idle_seconds, "A download ends after this long without data (s)");
  OPTION(download_total_seconds, "... or after this long in all (s)");
  OPTION(max_shot_bytes, "Largest shot fetched (bytes)");
  OPTION(max_body_bytes, "Largest listing page or control answer (bytes)");
  OPTION(max_event_message_bytes, "Largest event-channel message (bytes)");
  OPTION(max_json_depth, "Deepest JSON accepted from the device");
  OPTION(backoff_min_seconds, "Reconnect back-off, first (s); it doubles");
  OPTION(backoff_max_seconds, "Reconnect back-off, longest (s)");
  OPTION(engine_io_version, "Engine.IO protocol version");
  OPTION(ping_interval_override_ms, "Overrides the device's pingInterval when > 0 (ms)");
  OPTION(ping_timeout_override_ms, "Overrides the device's pingTimeout when > 0 (ms)");
  OPTION(store_write_fault, "Tests only: a full disk on demand");
}

void List(const std::string& prefix, const CamfiEmulatorOptions& o, Out* out) {
  [[maybe_unused]] const auto& [images, http_port, event_port, interval_seconds,
                                engine_io_version, ping_interval_ms, ping_timeout_ms, faults,
                                fault_every, seed, password, strict_path_encoding, store,
                                folder_size, files_page_limit, files_ignore_start, files_failures,
                                files_failure_status, files_failure_body] = o;
  OPTION(images, "Images shot, in this order");
  OPTION(http_port, "REST port (0: any free port)");
  OPTION(event_port, "Event channel port (0: any free port)");
  OPTION(interval_seconds, "Seconds between shots");
  OPTION(engine_io_version, "Engine.IO protocol version of the event channel");
  OPTION(ping_interval_ms, "pingInterval of the Engine.IO open packet (ms)");
  OPTION(ping_timeout_ms, "pingTimeout of the Engine.IO open packet (ms)");
  OPTION(faults, "Seeded faults");
  OPTION(fault_every, "A per-shot fault hits every this-many-th shot");
  OPTION(seed, "Seed of the fault offsets");
  OPTION(password, "Password of the auth fault");
  OPTION(strict_path_encoding, "Reject /raw/ paths whose slashes are not encoded as %2F");
  OPTION(store, "Card store of the device paths");
  OPTION(folder_size, "Files per DCIM folder before the next one");
  OPTION(files_page_limit, "/files paths per page at most (0: as many as asked)");
  OPTION(files_ignore_start, "/files ignores start (every page from the first file)");
  OPTION(files_failures, "The first listings answered with the failure status and body");
  OPTION(files_failure_status, "HTTP status of those failures");
  OPTION(files_failure_body, "Body of those failures");
}

void List(const std::string& prefix, const WatchedFolderOptions& o, Out* out) {
  [[maybe_unused]] const auto& [poll_seconds, stable_seconds, give_up_seconds, recursive,
                                state_file] = o;
  OPTION(poll_seconds, "How often the folder is listed (s)");
  OPTION(stable_seconds, "A file must keep its size and time this long before it is read (s)");
  OPTION(give_up_seconds, "A file unchanged this long but not a whole image is reported (s)");
  OPTION(recursive, "Sub-folders too, at any depth");
  OPTION(state_file, "Where each file handed on is recorded (empty: nowhere)");
}

void List(const std::string& prefix, const MergedSourceOptions& o, Out* out) {
  [[maybe_unused]] const auto& [order, queue_frames] = o;
  OPTION(order, "Order frames are handed on in: arrival, capture-time or round-robin");
  OPTION(queue_frames, "Frames read ahead per input before its reader waits");
}

void List(const std::string& prefix, const QualityTracker::Options& o, Out* out) {
  [[maybe_unused]] const auto& [sigma_source, sigma_px, prior_redundancy, min_views,
                                min_angle_deg, refresh_budget_ms] = o;
  OPTION(sigma_source, "Pixel noise of the uncertainties: fixed (sigma_px), model-rms (the model's RMS reprojection error) or a-posteriori (each point's and image's own residuals, the model's noise as a prior)");
  OPTION(sigma_px, "Pixel noise, standard deviation per coordinate, when fixed (and while the model has no residual)");
  OPTION(refresh_budget_ms, "Per update, at most this long measures again what a bundle only moved (the rest waits, oldest first), ms");
  OPTION(prior_redundancy, "a-posteriori: the model's noise counts as this many of an element's own residuals");
  OPTION(min_views, "A well-covered point is seen by at least this many images");
  OPTION(min_angle_deg, "... under a largest triangulation angle of at least this many degrees");
}

void List(const std::string& prefix, const Coverage::Options& o, Out* out) {
  [[maybe_unused]] const auto& [min_views, min_angle_deg, max_incidence_deg, max_points,
                                max_rays_per_point, max_suggestions, min_suggestion_share,
                                max_step_deg] = o;
  OPTION(min_views, "A well-covered face is faced by at least this many cameras (a run takes quality.min_views)");
  OPTION(min_angle_deg, "... with a largest angle between their rays of at least this (a run takes quality.min_angle_deg)");
  OPTION(max_incidence_deg, "A camera counts for a face it looks at less obliquely than this, degrees from its normal");
  OPTION(max_points, "The surface is built from at most this many points, evenly taken");
  OPTION(max_rays_per_point, "... each carving with at most this many of its rays");
  OPTION(max_suggestions, "Suggested viewpoints, at most");
  OPTION(min_suggestion_share, "A side is suggested when at least this share of the reachable surface is under-covered there");
  OPTION(max_step_deg, "A suggestion is at most this far round the object from the nearest shot, degrees (a step towards a far side)");
}

void List(const std::string& prefix, const ViewServerOptions& o, Out* out) {
  [[maybe_unused]] const auto& [lan, port, token, max_clients, max_queued_messages,
                                keepalive_seconds, write_timeout_seconds, thumbnail_width,
                                max_list_thumbnails, three_js, orbit_controls_js] = o;
  OPTION(lan, "Serve the LAN (with a token) instead of this machine only");
  OPTION(port, "HTTP port (0: any free port)");
  OPTION(token, "The LAN token (empty: 128 random bits)");
  OPTION(max_clients, "Event streams served at once");
  OPTION(max_queued_messages, "Messages queued for a client before the whole model replaces them");
  OPTION(keepalive_seconds, "A comment goes to an idle stream this often (s)");
  OPTION(write_timeout_seconds, "A browser that takes no bytes this long is dropped (s)");
  OPTION(thumbnail_width, "Width of the shots' thumbnails (px)");
  OPTION(max_list_thumbnails, "Thumbnails kept of pending and rejected shots (the oldest go first)");
  OPTION(three_js, "three.js library file");
  OPTION(orbit_controls_js, "three.js orbit controls file");
}

void List(const std::string& prefix, const Camera& o, Out* out) {
  [[maybe_unused]] const auto& [model_id, width, height, params, readout_time] = o;
  OPTION(model_id, "Camera model (COLMAP's name)");
  OPTION(width, "Image width (px)");
  OPTION(height, "Image height (px)");
  OPTION(params, "Parameters in COLMAP's order");
  OPTION(readout_time, "Rolling-shutter readout time (s; 0: global shutter)");
}

void List(const std::string& prefix, const SyntheticCaptureOptions& o, Out* out) {
  [[maybe_unused]] const auto& [num_views, path_length, supersampling, seed, camera] = o;
  OPTION(num_views, "Views rendered");
  OPTION(path_length, "Length of the walk along the back wall (m)");
  OPTION(supersampling, "Sub-pixel rays per pixel side");
  OPTION(seed, "Scene and path seed");
  NESTED(camera);
}

#undef OPTION
#undef NESTED

struct Root {
  const char* name;
  const char* type;
  const char* header;
};
// The order of the page.
const Root kRoots[] = {
    {"engine", "Engine::Options", "core/engine.h"},
    {"checkpoint", "Checkpointer::Options", "io/run/checkpoint.h"},
    {"camfi", "CamfiOptions", "io/camfi/camfi_client.h"},
    {"camfi_emulator", "CamfiEmulatorOptions", "io/camfi/camfi_emulator.h"},
    {"watch", "WatchedFolderOptions", "io/sources/watched_folder.h"},
    {"merged_source", "MergedSourceOptions", "io/sources/merged_source.h"},
    {"view", "ViewServerOptions", "io/view/view_server.h"},
    {"quality", "QualityTracker::Options", "quality/quality_tracker.h"},
    {"retrieval_training", "RetrievalTrainingOptions", "retrieval/retrieval_model.h"},
    {"synthetic_capture", "SyntheticCaptureOptions", "io/synthetic/synthetic_source.h"},
};

std::string RootOf(const std::string& key) { return key.substr(0, key.find('.')); }

// A table cell: '|' would end it, even inside a code span.
std::string Cell(const std::string& text) {
  std::string cell;
  for (const char c : text) {
    if (c == '|') cell += '\\';
    cell += c == '\n' ? ' ' : c;
  }
  return cell;
}

// A code span around any text: fenced by more backticks than it holds in a
// row, padded when it starts or ends with one.
std::string Code(const std::string& text) {
  std::size_t longest = 0, run = 0;
  for (const char c : text) {
    run = c == '`' ? run + 1 : 0;
    longest = std::max(longest, run);
  }
  const std::string fence(longest + 1, '`');
  const bool pad = !text.empty() && (text.front() == '`' || text.back() == '`');
  return fence + (pad ? " " : "") + text + (pad ? " " : "") + fence;
}

// The content of the code span that ends `text` (spaces after it allowed),
// if one does: its closing run of backticks, back to the nearest run of as
// many. Markdown drops one space of padding on each side.
std::optional<std::string> CodeSpanBefore(const std::string& text) {
  const std::size_t last = text.find_last_not_of(' ');
  if (last == std::string::npos || text[last] != '`') return std::nullopt;
  // [begin, end) of a run of backticks ending at `run_last`.
  const auto run_begin = [&](std::size_t run_last) {
    const std::size_t before = text.find_last_not_of('`', run_last);
    return before == std::string::npos ? 0 : before + 1;
  };
  const std::size_t close = run_begin(last);
  const std::size_t fence = last + 1 - close;
  std::size_t pos = close;
  while (pos > 0) {
    const std::size_t open_last = text.rfind('`', pos - 1);
    if (open_last == std::string::npos) break;
    const std::size_t open = run_begin(open_last);
    if (open_last + 1 - open == fence) {
      std::string value = text.substr(open_last + 1, close - open_last - 1);
      if (value.size() >= 2 && value.front() == ' ' && value.back() == ' ' &&
          value.find_first_not_of(' ') != std::string::npos) {
        value = value.substr(1, value.size() - 2);
      }
      return value;
    }
    pos = open;
  }
  return std::nullopt;
}

}  // namespace

std::vector<OptionDefault> ListOptionDefaults() {
  Out out;
  // Default-constructed here, so lambda-initialised members (local_ba,
  // global_ba) carry their initialisers' values.
  List("engine.", Engine::Options(), &out);
  List("checkpoint.", Checkpointer::Options(), &out);
  List("camfi.", CamfiOptions(), &out);
  List("camfi_emulator.", CamfiEmulatorOptions(), &out);
  List("watch.", WatchedFolderOptions(), &out);
  List("merged_source.", MergedSourceOptions(), &out);
  List("view.", ViewServerOptions(), &out);
  List("quality.", QualityTracker::Options(), &out);
  List("coverage.", Coverage::Options(), &out);
  List("retrieval_training.", RetrievalTrainingOptions(), &out);
  List("synthetic_capture.", SyntheticCaptureOptions(), &out);
  return out;
}

std::string RenderOptionDefaults(const std::vector<OptionDefault>& defaults) {
  std::ostringstream page;
  page << "# Option defaults\n\n"
       << "Generated by `build/flysfm defaults > docs/defaults.md`: do not edit this page, "
          "run that again after changing an option. tests/tools/defaults_test.cc fails "
          "while the page and the code disagree.\n\n"
       << "Every member of every options struct with its default as the code defines it "
          "(read from a default-constructed struct). A command may set some of them "
          "otherwise from its flags (`build/flysfm <command> --help`). Keys follow the C++ "
          "member names from the root below; booleans are true/false, numbers as the code "
          "holds them (doubles to ten significant digits), empty strings \"\", empty lists "
          "and unset callbacks none.\n\n";
  if (!defaults.empty()) {
    const OptionDefault& example = defaults.front();
    page << "Another page quotes a default with a code span followed by an HTML comment "
            "naming its key, checked by the same test against this page: "
         << Code(Code(example.value) + "<!-- default " + example.key + " -->") << ".\n";
  }
  // Roots in kRoots' order, then any other in order of appearance.
  std::vector<std::string> roots;
  for (const Root& root : kRoots) roots.push_back(root.name);
  for (const OptionDefault& entry : defaults) {
    if (std::find(roots.begin(), roots.end(), RootOf(entry.key)) == roots.end()) {
      roots.push_back(RootOf(entry.key));
    }
  }
  for (const std::string& root : roots) {
    bool any = false;
    for (const OptionDefault& entry : defaults) {
      if (RootOf(entry.key) != root) continue;
      if (!any) {
        page << "\n## " << root << "\n\n";
        for (const Root& known : kRoots) {
          if (root == known.name) {
            page << "`" << known.type << "` (" << known.header << ").\n\n";
          }
        }
        page << "| key | default | meaning |\n|---|---|---|\n";
        any = true;
      }
      page << "| " << Cell(Code(entry.key)) << " | " << Cell(Code(entry.value)) << " | "
           << Cell(entry.help) << " |\n";
    }
  }
  return page.str();
}

std::vector<DefaultMarker> FindDefaultMarkers(const std::string& text) {
  static const std::regex comment(R"(<!--\s*default\s+([^\s>]*)\s*-->)");
  std::vector<DefaultMarker> markers;
  std::istringstream lines(text);
  std::string line;
  for (int number = 1; std::getline(lines, line); ++number) {
    for (auto it = std::sregex_iterator(line.begin(), line.end(), comment);
         it != std::sregex_iterator(); ++it) {
      DefaultMarker marker;
      marker.line = number;
      marker.key = (*it)[1].str();
      std::optional<std::string> value = CodeSpanBefore(line.substr(0, it->position(0)));
      if (value) {
        marker.value = *value;
        marker.has_value = true;
      }
      markers.push_back(marker);
    }
  }
  return markers;
}

std::vector<std::string> CheckDefaultMarkers(const std::string& text, const std::string& file,
                                             const std::vector<OptionDefault>& defaults) {
  std::map<std::string, std::string> value_of;
  for (const OptionDefault& entry : defaults) value_of[entry.key] = entry.value;
  std::vector<std::string> problems;
  for (const DefaultMarker& marker : FindDefaultMarkers(text)) {
    const std::string where = file + ":" + std::to_string(marker.line) + ": ";
    const auto it = value_of.find(marker.key);
    if (it == value_of.end()) {
      problems.push_back(where + "unknown option key '" + marker.key +
                         "' (docs/defaults.md lists the keys)");
    } else if (!marker.has_value) {
      problems.push_back(where + "no code span before the marker of " + marker.key +
                         " (write `" + it->second + "`<!-- default " + marker.key + " -->)");
    } else if (marker.value != it->second) {
      problems.push_back(where + marker.key + " is quoted as `" + marker.value +
                         "`, its default is `" + it->second + "`");
    }
  }
  return problems;
}

}  // namespace flysfm
