#pragma once

// The on-the-fly engine: one image in, its pose and new 3D points out, before
// the next image arrives. AddImage follows the paper's Fig. 2 step by step;
// each step is a class of its own (pair verification, initializer,
// registrar, triangulator, pending pool), as COLMAP splits its incremental
// mapper. Single-threaded and deterministic for a given input order.

#include <deque>
#include <filesystem>
#include <functional>
#include <istream>
#include <map>
#include <memory>
#include <optional>
#include <ostream>
#include <string>
#include <tuple>
#include <unordered_set>
#include <unordered_map>
#include <vector>

#include <opencv2/core.hpp>

#include "bundle/association_tree.h"
#include "bundle/bundle_adjuster.h"
#include "core/scene/frame.h"
#include "core/scene/image_result.h"
#include "core/initializer.h"
#include "core/lsm_image_store.h"
#include "core/pair_verification.h"
#include "core/pending_pool.h"
#include "core/scene/reconstruction.h"
#include "core/registration.h"
#include "core/scene_bundle.h"
#include "core/sub_models.h"
#include "core/triangulator.h"
#include "matching/features.h"
#include "matching/image_decode.h"
#include "matching/match_store.h"
#include "retrieval/image_retriever.h"

namespace flysfm {

// A frame decoded, in grey, and its features: the part of AddImage that
// needs nothing of the model. The ingest side may prepare the next image on
// the second core while the engine works on this one (docs/architecture.md).
struct PreparedFrame {
  Frame frame;    // name and times; the encoded bytes are released
  cv::Mat image;  // BGR, perhaps reduced (DecodedImage); empty when decoding failed
  cv::Mat grey;   // full size
  std::string error;  // why decoding failed; empty on success
  std::optional<double> exif_focal_length_px;
  std::string camera_identity;  // body, lens and zoom from the EXIF
  FeatureSet features;
  double decode_ms = 0;
  double features_ms = 0;
};

class Engine {
 public:
  struct Options {
    // Bounds on an image's bytes and pixels before it is decoded (Prepare).
    DecodeOptions decode;
    SiftOptions sift;
    ImageRetrieverOptions retrieval;
    // Matching, two-view geometry and LSM refinement of each candidate pair.
    PairVerifier::Options verification;
    // Once the model exists, candidates are matched in retrieval order until
    // this many pairs verify: matching is the costliest stage (the paper's
    // Table II), and past eight overlapping views further pairs add little
    // to registration or triangulation (fr1_xyz: the same ATE with 8 as with
    // 12). Retrieval's top-N bounds the search.
    int max_verified_pairs = 8;
    LsmImageStore::Options lsm_images;
    Initializer::Options initialization;
    Registrar::Options registration;
    Triangulator::Options triangulation;

    // Local BA over the hierarchical association tree (paper Sect. III-D).
    HierarchicalAssociationTree::Options ba_tree;
    // false: the same images in a plain local BA (k = 1, nothing fixed but
    // the images outside the tree), for the ablation.
    bool hierarchical_weights = true;
    // The block starts close to its optimum (each of its images was adjusted
    // when it registered): on fr1_xyz 3 iterations gave the same ATE as 10.
    BundleAdjuster::Options local_ba = [] {
      BundleAdjuster::Options options;
      options.max_num_iterations = 3;
      return options;
    }();
    // Per point, at most this many observations from images held constant
    // (the fixed ripple and images outside the tree; 0: all). Video tracks
    // run over dozens of frames; a few fixed views pin a point as well.
    int ba_max_constant_observers = 2;
    // Finish() runs a global BA over everything with these options. Global
    // BAs estimate a rolling shutter's readout time from video frames (their
    // motion from their neighbours in time, scene_bundle.h); photos are left
    // as taken by a still camera.
    bool final_global_ba = true;
    BundleAdjuster::Options global_ba = [] {
      BundleAdjuster::Options options;
      options.refine_readout_time = true;
      return options;
    }();
    // Data snooping (SnoopOutliers; 0: none) ends Finish's global BA, and
    // each round of refinement between shots: each image's observations
    // beyond this quantile of its own noise go, and the poses and points are
    // adjusted again. The 4 px filter below is the on-the-fly model's, whose
    // noise is not yet known; an adjusted model's errors are a tenth or two
    // of a pixel with a heavy tail (observations measured less well than the
    // rest) that a BA with one weight treats alike with the good ones.
    // docs/engine.md, step 11 and "Refinement between shots".
    double outlier_quantile = 0.99;
    // The snooping's adjustments at most (SnoopOutliers): they end once none
    // leaves an observation beyond its bound, after 3-5 on the photo sets
    // and rendered sessions measured (docs/engine.md, step 11); the bound
    // holds a snooping's cost on a long session to a few BAs, each starting
    // near its optimum.
    int outlier_max_rounds = 10;

    // After each BA: observations farther than this from their projection are
    // dropped, then points seen under less than the angle.
    double filter_max_error_px = 4.0;
    double filter_min_tri_angle_deg = 1.5;

    // Unknown intrinsics: SIMPLE_RADIAL with the focal length from the
    // image's EXIF, else this many times the image's longer side (1.2: a
    // 45 deg field of view, typical of the normal lenses photogrammetry
    // uses); refined in the global BAs either way.
    double unknown_focal_factor = 1.2;
    // While guessed intrinsics are being refined, a global BA runs each time
    // the model has grown by this factor since the last one, as COLMAP's
    // mapper schedules its global BAs: the whole model follows a focal length
    // that moves, where the local BA would bend it against the images it
    // holds fixed. A camera is calibrated once three such BAs in a row, each
    // run to convergence, move its focal length by less than
    // `self_calibration_converged_change` (relative; a two-view model
    // hardly constrains it); when every camera is, per-image cost is the
    // local BA's again. Growth 0: no such BA.
    double self_calibration_growth = 1.25;
    double self_calibration_converged_change = 0.002;
    // A BA in AddImage is waited for whole, and costs what its observations
    // and iterations cost: past this many observations in the model, a
    // scheduled BA gets the iterations global_ba allows spread over them
    // (half as many for twice the observations), at least
    // `self_calibration_min_iterations`; the next one goes on from where it
    // stopped. On a narrow-baseline video the focal length never settles to
    // 0.2 %, and the schedule's 50-iteration BAs grew to 30-40 s a frame
    // (fr1_xyz, 290 frames); 10 000 observations take about a second, and
    // the photo sets measured converged below 6 000.
    int self_calibration_max_observations = 10000;
    int self_calibration_min_iterations = 5;

    // Refinement between shots (Engine::Refine; docs/engine.md, "Refinement
    // between shots"): what COLMAP does with all photos at hand, done while
    // the engine would otherwise wait for the next one.
    struct Refinement {
      // Off: the model is what each AddImage left, and Finish's global BA.
      bool enabled = true;
      // Each image is matched with retrieval's top this many; its arrival
      // stopped at max_verified_pairs verified. On a set of up to this many
      // images plus one the match graph becomes exhaustive, but for the
      // pairs already linked (max_shared_points).
      int candidates_per_image = 30;
      // A candidate pair whose images already observe this many points in
      // common, through tracks the model joined, is not matched: its matches
      // would mostly repeat what those tracks hold (neighbours in a video, or
      // photos a few steps apart), at the cost of a verification each. A
      // revisit whose tracks were never joined shares few or none, and is.
      int max_shared_points = 100;
      // A slice's work at most: pairs verified, or images triangulated. A
      // slice also ends as soon as an image waits, so these bound the wait
      // of a new image (one pair or one image's triangulation at most).
      int pairs_per_slice = 8;
      int images_per_slice = 16;
      // After a global BA, every image's tracks are continued, completed and
      // merged again, and its free keypoints triangulated (observations the
      // filter dropped, rays that were too close before). While that changes
      // more than this share of the observations, another global BA follows,
      // at most `max_adjustments` in a row without a new image (COLMAP's
      // mapper iterates the same way).
      double min_changed_observations = 0.005;
      int max_adjustments = 3;
      // Past this many observations in the model, the BA refines only the
      // images registered last (whose poses only local BAs have seen; as
      // many as hold this many observations, at least two) and their
      // points, the rest held. A BA iteration is what a new image may have
      // to wait for, and its cost follows its residuals, not its images: on
      // fr1_xyz the 50 frames registered last (60 000 observations) took
      // 70-180 ms an iteration, the whole 330 about 1.6 s. So bounded, an
      // iteration costs the same at image 50 and at image 500, and on
      // photos with many points each as on video frames. While guessed
      // intrinsics converge the BA stays global.
      int max_adjusted_observations = 20000;

      bool Check() const;
    };
    Refinement refinement;

    // Sub-models (docs/engine.md, "Sub-models"): a shot that fits no model
    // starts one of its own with a waiting shot it forms an initial pair
    // with, instead of waiting without a pose; a later shot registered in one
    // sub-model whose matches reach another's points links the two, and the
    // smaller is merged into the larger.
    SubModelOptions sub_models;

    // The end of a run (Finish): what refinement between images left undone,
    // bounded. A run that was refined to its end between images (live
    // capture, a paced batch) needs no more; one fed as fast as the engine
    // goes (an unpaced batch) gets a global BA and the data snooping, whose
    // cost these bound (docs/engine.md, "Finish").
    struct Finishing {
      // The run's loop is over, so the second core, which prepared the next
      // image, is free for the end's adjustments.
      int num_threads = 2;
      // An adjustment of the end stops once an iteration lowers the cost by
      // less than this share. On fr1_xyz (330 frames) the global BA reaches
      // in 6 iterations (1e-4) the ATE that 20 give (1e-6): 0.344 against
      // 0.340 cm, in 9.5 s against 25 s.
      double function_tolerance = 1e-4;
      // The end's adjustments (the global BA, then the snooping's) start
      // no iteration that would, at the last one's cost, bring the end's
      // time (its retries included) past this share of the engine's own
      // time in the run (its AddImage and Refine calls), or past
      // `min_seconds` when that is more: the end costs the run a
      // tenth at most whatever the session's length, and a small model
      // (a few dozen photos, a second's adjustments) is always adjusted to
      // convergence. On fr1_xyz the first BA iterations do most: 3 give an
      // ATE of 0.352 cm in 3.3 s, 4 0.348 cm in 4.5 s.
      double max_share_of_run = 0.1;
      double min_seconds = 5;

      bool Check() const;
    };
    Finishing finishing;

    // True when every option is in range; otherwise false, and `problem`
    // (when given) names the first bad option.
    bool Check(std::string* problem = nullptr) const;
  };

  // `camera`: known intrinsics shared by all images (held fixed unless
  // options.local_ba or global_ba refine them); without it each image size
  // gets a camera with a guessed focal length, refined in the global BAs.
  // `retrieval_model`: a trained model file's content; without it retrieval
  // bootstraps from the session.
  // Throws std::invalid_argument naming a bad option or camera.
  explicit Engine(const Options& options, std::optional<Camera> camera = std::nullopt,
                  std::shared_ptr<const RetrievalModel> retrieval_model = nullptr);
  // Its steps hold pointers to its model and stores.
  Engine(const Engine&) = delete;
  Engine& operator=(const Engine&) = delete;

  // Decoding and feature extraction with `options`; thread-safe, so it may
  // run on another thread than the engine's.
  static PreparedFrame Prepare(const Frame& frame, const Options& options);

  // Processes one fly-in image. Returns its result first, then one for each
  // pending image that registered thanks to it. Each result's times are the
  // work done for that image (decoding and features included, wherever they
  // ran), and the totals of one call add up to the call's work.
  std::vector<ImageResult> AddImage(const Frame& frame);
  std::vector<ImageResult> AddImage(PreparedFrame prepared);

  // One slice of refinement, for when no image is waiting (live: between
  // shots; batch: between paced images and at the end). Each call does the
  // first of these that has work, in this order:
  //   kMatch: candidate pairs of retrieval that were not tried yet;
  //   kTriangulate: images with new verified pairs (continuation,
  //     completion, merging, new tracks), then a try of waiting images;
  //   kAdjust: a global BA (beyond refinement.max_adjusted_observations,
  //     one of the images registered last) when the model changed since the
  //     last one, and a filter of every point;
  //   kRetriangulate: every registered image's tracks again;
  //   kSnoop: once BA and retriangulation are done, data snooping
  //     (SnoopOutliers) over the images that BA adjusts, unless guessed
  //     intrinsics are still converging.
  // kNone: nothing to do until the next image. `should_yield` is polled
  // between pairs, images and BA iterations; when it turns true the slice
  // ends early (an unfinished BA is run again later). Without it, the
  // sequence of slices depends only on the images given.
  struct RefinementSlice {
    enum class Step { kNone, kMatch, kTriangulate, kAdjust, kRetriangulate, kSnoop };
    Step step = Step::kNone;
    int num_pairs_tried = 0;
    int num_pairs_verified = 0;
    // Candidates left unmatched: their images share max_shared_points.
    int num_pairs_linked = 0;
    int num_images_triangulated = 0;
    Triangulator::Summary triangulation;
    // Sub-models the new pairs linked and merged (kTriangulate).
    int num_merged_models = 0;
    bool global_ba = false;
    BundleAdjuster::Summary ba;
    OutlierSnooping snooping;
    // Waiting images that registered in this slice.
    std::vector<ImageResult> registered;
  };
  RefinementSlice Refine(const std::function<bool()>& should_yield = {});
  static const char* RefinementStepName(RefinementSlice::Step step);
  // Refine() until nothing is left: the end of a run that refined between
  // images. Returns the images registered meanwhile. `on_slice`, when
  // given, sees each slice (a progress line).
  std::vector<ImageResult> RefineToEnd(
      const std::function<void(const RefinementSlice&)>& on_slice = {});
  // What refinement did so far, RefineToEnd's included.
  struct RefinementTotals {
    int num_slices = 0;
    int num_pairs_tried = 0;
    int num_pairs_verified = 0;
    int num_pairs_linked = 0;
    int num_global_bas = 0;
    std::size_t num_snooped = 0;  // observations the snooping dropped
    double ms = 0;
  };
  const RefinementTotals& refinement_totals() const { return refinement_.totals; }

  // What a long step of Finish is doing, for a progress line and the live
  // view.
  struct FinishProgress {
    enum class Step { kRetry, kAdjust, kSnoop };
    Step step = Step::kRetry;
    // kSnoop: the adjustment of the snooping, of at most max_rounds.
    int round = 0;
    int max_rounds = 0;
    // The running BA's iteration (0: its start), of at most max_iterations.
    int iteration = 0;
    int max_iterations = 0;
    // Since Finish began, and the most its adjustments may still take (their
    // budget, Options::Finishing).
    double elapsed_s = 0;
    std::optional<double> remaining_s;
  };
  static const char* FinishStepName(FinishProgress::Step step);

  // End of a batch: pending images get a last try, then the optional global
  // BA. Returns results for images registered by the last try. A run that
  // refines between images refines until nothing is left before this
  // (the run loop, io/run); one fed as fast as the engine goes had no idle
  // time, and gets the global BA alone. `progress`, when given, is told
  // each step and each BA iteration.
  std::vector<ImageResult> Finish(
      const std::function<void(const FinishProgress&)>& progress = {});

  // Checkpointing (docs/engine.md, "Resume"). The state splits into what
  // an image fixes once and for all, written once: its record (name, file,
  // features, verified matches with the images before it), complete when
  // AddImage returns, and its LSM windows, once it keeps only those
  // (lsm_images().WriteWindows); the retrieval model learnt from the
  // session, which changes only at a retraining (a new
  // RetrievalModelVersion); and a snapshot of the rest, whose size grows
  // with the model. Restore continues the same model on an engine made with
  // the same camera and retrieval as the checkpointed one, before any
  // image.
  void WriteImageRecord(image_t image_id, std::ostream& out) const;
  int RetrievalModelVersion() const { return retriever_.model_version(); }
  void WriteRetrievalModel(std::ostream& out) const { retriever_.WriteModel(out); }
  void WriteSnapshot(std::ostream& out) const;
  // The files of a checkpoint by image id (or model version); nullptr when
  // not written. A missing record or retrieval model is an error, missing
  // windows leave the image out of LSM.
  struct CheckpointFiles {
    std::function<std::unique_ptr<std::istream>(image_t)> record;
    std::function<std::unique_ptr<std::istream>(image_t)> windows;
    std::function<std::unique_ptr<std::istream>(int)> retrieval_model;
  };
  // Whole images LSM still searches are decoded again from their files.
  // Throws std::runtime_error, naming the problem, on a truncated,
  // inconsistent or mismatched checkpoint; the engine is unusable then.
  void Restore(std::istream& snapshot, const CheckpointFiles& files);

  const Options& options() const { return options_; }
  const Reconstruction& reconstruction() const { return reconstruction_; }
  // What the model's changes were since the last call (the live view's
  // incremental updates).
  Reconstruction::Changes TakeReconstructionChanges() { return reconstruction_.TakeChanges(); }
  // What LSM keeps of the images (its memory, for benchmarks and tests).
  const LsmImageStore& lsm_images() const { return lsm_images_; }
  // Whether the image came from a file, from which a restored engine can
  // cut its LSM windows again (a checkpoint then need not hold them).
  bool HasImageFile(image_t image_id) const;
  std::vector<std::string> PendingImageNames() const;
  int num_rejected() const { return num_rejected_; }
  bool initialized() const { return initialized_; }

 private:
  // AddImage's steps (AddImage adds their time to work_seconds_).
  std::vector<ImageResult> AddPreparedImage(PreparedFrame prepared);
  // The camera shared by the images of this size and camera identity (body,
  // lens, zoom setting, as the EXIF tells them); created with the first one
  // (and its EXIF focal length, when intrinsics are unknown).
  camera_t CameraFor(const PreparedFrame& prepared);
  // Steps 4-5 for every candidate: the verified matches go to the match
  // store, LSM-refined keypoints into the model, and (until the model
  // exists) the pairs' geometry to the initializer.
  void VerifyPairs(image_t image_id, const std::vector<RetrievalCandidate>& candidates,
                   ImageResult* result);
  // Step 6: the best remembered pair starts the model; once it exists, the
  // best pair of `image_id` with a waiting image starts a sub-model.
  bool Initialize(ImageResult* result, image_t image_id = kInvalidImageId);
  // Step 10c: the sub-models the registered `image_id` links to its own are
  // merged with it.
  void LinkSubModels(image_t image_id, ImageResult* result);
  // Steps 7-10 for an image that may register now.
  bool RegisterAndExtend(image_t image_id, ImageResult* result);
  // Steps 8-10 once `image_id` is registered.
  void TriangulateAndAdjust(image_t image_id, ImageResult* result);
  // Step 11: waiting images whose neighbourhood grew are tried again, while
  // any registers; each that does gets its result appended to `results`
  // (results[0], the new image, reports its own registration in place).
  void RetryPending(std::vector<ImageResult>* results);
  // Step 10b: the scheduled global BA while guessed intrinsics converge.
  void AdjustWhileSelfCalibrating(ImageResult* result);
  // Step 12: the images LSM will not search again keep only windows.
  void KeepLsmWindows();
  // Whether refinement left nothing to do, its last BA and snooping having
  // covered every image: Finish then adjusts nothing more.
  bool RefinedToTheEnd() const;
  // RetryPending with no new image (refinement, Finish).
  std::vector<ImageResult> RetryWaiting();
  // The steps of Refine.
  void MatchMorePairs(const std::function<bool()>& should_yield, RefinementSlice* slice);
  void TriangulateQueued(std::deque<image_t>* images, const std::function<bool()>& should_yield,
                         RefinementSlice* slice);
  // The images refinement's BAs and snooping adjust (weight 1): all while
  // the model holds at most refinement.max_adjusted_observations or guessed
  // intrinsics converge, else the images registered last.
  std::unordered_map<image_t, double> RefinementWindow() const;
  void AdjustEverything(const std::function<bool()>& should_yield, RefinementSlice* slice);
  void SnoopEverything(const std::function<bool()>& should_yield, RefinementSlice* slice);
  int NumRegisteredNeighbours(image_t image_id) const;
  std::vector<int> RetrievalNeighbours(image_t image_id, int n) const;
  ImageResult ResultFor(image_t image_id) const;
  void Finalize(ImageResult* result) const;

  Options options_;
  std::optional<Camera> known_camera_;
  Reconstruction reconstruction_;
  ImageRetriever retriever_;
  MatchStore matches_;
  LsmImageStore lsm_images_;
  PairVerifier verifier_;
  Initializer initializer_;
  Registrar registrar_;
  Triangulator triangulator_;
  PendingPool pending_;
  // What matching and colouring need of each image seen, and the file it
  // came from (empty for bytes from elsewhere).
  std::unordered_map<image_t, FeatureSet> features_;
  std::unordered_map<image_t, std::filesystem::path> image_files_;
  std::map<std::tuple<int, int, std::string>, camera_t> camera_by_identity_;
  bool initialized_ = false;
  // Shots posed in two sub-models, by the pair of sub-models (the lower id
  // first): a link's evidence as it gathers (LinkSubModels).
  std::map<std::pair<model_t, model_t>, std::vector<SubModelView>> link_views_;
  int num_rejected_ = 0;
  // The engine's own time in AddImage and Refine: what bounds the end.
  double work_seconds_ = 0;
  // Cameras whose guessed intrinsics have not converged yet, each with the
  // number of global BAs in a row that hardly moved its focal length; and
  // the model size that triggers the next global BA.
  std::map<camera_t, int> self_calibrating_;
  std::size_t next_self_calibration_images_ = 0;

  // What refinement has left to do. Of it only the pairs tried at each
  // image's arrival are checkpointed (in its record): a restored engine
  // tries every other candidate pair again, and adjusts once.
  struct RefinementState {
    // Images whose retrieval candidates are not all tried, in arrival
    // order; the pairs tried so far, on arrival or later (ImagePairKey).
    std::deque<image_t> to_match;
    std::unordered_set<std::uint64_t> tried_pairs;
    // Images with new verified pairs, ascending.
    std::deque<image_t> to_triangulate;
    // The model changed since the last global BA of the refinement.
    bool adjust = false;
    int num_adjustments = 0;  // in a row, without a new image
    // Registered images to triangulate again after that BA, and the
    // observations it left.
    std::deque<image_t> to_retriangulate;
    std::size_t observations_after_adjust = 0;
    int merged_since_adjust = 0;
    // A BA completed since the last snooping.
    bool snoop = false;
    // The last snooping covered every registered image, and nothing
    // changed since (a registration or a refinement step sets it false).
    bool snooped_everything = false;
    RefinementTotals totals;
  };
  RefinementState refinement_;
};

}  // namespace flysfm
