#pragma once

// The on-the-fly engine: one image in, its pose and new 3D points out, before
// the next image arrives. AddImage follows the paper's Fig. 2 step by step:
// features, retrieval, matching, two-view geometry, LSM refinement, then
// initialisation or registration (with LSM densification), triangulation,
// hierarchical weighted local bundle adjustment and filtering. Images that
// cannot register yet wait in a pending pool and are retried as the model
// grows. Single-threaded and deterministic for a given input order.

#include <list>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <unordered_map>
#include <vector>

#include <opencv2/core.hpp>

#include "bundle/association_tree.h"
#include "bundle/bundle_adjuster.h"
#include "core/frame.h"
#include "core/reconstruction.h"
#include "geometry/absolute_pose.h"
#include "geometry/triangulation.h"
#include "geometry/two_view_geometry.h"
#include "lsm/densify.h"
#include "lsm/lsm.h"
#include "lsm/refine_matches.h"
#include "matching/features.h"
#include "matching/match_store.h"
#include "matching/matcher.h"
#include "retrieval/image_retriever.h"

namespace flysfm {

// Milliseconds spent in each stage for one image.
struct StageTimes {
  double decode = 0;
  double features = 0;
  double retrieval = 0;
  double matching = 0;
  double verification = 0;
  double lsm = 0;
  double registration = 0;
  double triangulation = 0;
  double ba = 0;
  double total = 0;
};

enum class ImageStatus {
  kRegistered,
  kPending,   // waits in the pending pool; retried as the model grows
  kRejected,  // unreadable: counted and skipped
};
const char* ImageStatusName(ImageStatus status);

struct ImageResult {
  std::string name;
  image_t image_id = kInvalidImageId;
  ImageStatus status = ImageStatus::kPending;
  // Why the image is pending or rejected; empty when registered.
  std::string reason;
  std::optional<Rigid3d> cam_from_world;
  int num_features = 0;
  int num_candidates = 0;      // retrieved images
  int num_verified_pairs = 0;  // candidates passing two-view geometry
  int num_lsm_rejected = 0;    // verified matches LSM dropped as outliers
  int num_correspondences = 0; // 2D-3D, before RANSAC (incl. densified)
  int num_densified = 0;       // 2D-3D added by LSM densification
  int num_pose_inliers = 0;
  int num_new_points = 0;      // triangulated with this image
  int num_observations = 0;    // of this image after filtering
  // The local BA: images refined, images held constant, points, iterations.
  int ba_free_images = 0;
  int ba_images = 0;
  int ba_points = 0;
  int ba_iterations = 0;
  // The model after this image.
  int model_images = 0;
  int model_points = 0;
  StageTimes times;
};

// A frame decoded, in grey, and its features: the part of AddImage that
// needs nothing of the model. The ingest side may prepare the next image on
// the second core while the engine works on this one (ARCHITECTURE.md).
struct PreparedFrame {
  Frame frame;    // name and times; the encoded bytes are released
  cv::Mat image;  // BGR; empty when decoding failed
  cv::Mat grey;
  std::string error;  // why decoding failed; empty on success
  std::optional<double> exif_focal_length_px;
  FeatureSet features;
  double decode_ms = 0;
  double features_ms = 0;
};

class Engine {
 public:
  struct Options {
    SiftOptions sift = DefaultSiftOptions();
    ImageRetrieverOptions retrieval;
    MatchOptions matching;
    // Candidates are matched in retrieval order until this many pairs pass
    // two-view geometry: matching is the costliest stage (the paper's Table
    // II), and past eight overlapping views further pairs add little to
    // registration or triangulation (fr1_xyz: the same ATE with 8 as with
    // 12). Retrieval's top-N bounds the search.
    int max_verified_pairs = 8;
    TwoViewGeometryOptions two_view;
    LsmOptions lsm;
    // The paper's LSM steps, each switchable for ablations.
    bool lsm_refinement = true;
    bool lsm_densification = true;
    DensifyOptions densify;
    // LSM images (pyramids) are built once per image and kept, most recently
    // used first, within this budget: a new image meets mostly recent ones.
    int lsm_cache_megabytes = 512;
    // Densification looks for the points of this many registered neighbours
    // (those sharing the most verified matches), as the local BA's first
    // ripple does.
    int densify_max_references = 8;
    // At most this many points are tried per image, longest tracks first:
    // enough to steady the pose, while the per-image observation count (and
    // with it every later BA) stays bounded. On fr1_xyz 300 cost 25 ms more
    // of local BA per image than 150, for the same ATE.
    int densify_max_candidates = 150;

    // Initialisation: the verified pair with the most inliers among those
    // with at least `init_min_num_inliers` and a median triangulation angle
    // of at least `init_min_tri_angle_deg`. The paper asks for 60-120 deg on
    // wide-baseline photo sets; a hand-held video moves a few centimetres a
    // second, so the threshold is the smallest angle that still fixes depth
    // well (COLMAP's incremental mapper uses 16 deg on photo sets).
    int init_min_num_inliers = 100;
    double init_min_tri_angle_deg = 4.0;
    // The initial pair must triangulate at least this many points.
    int init_min_num_points = 50;

    // Registration: at least this many 2D-3D correspondences to try.
    int min_num_correspondences = 20;
    AbsolutePoseOptions absolute_pose;
    TriangulationOptions triangulation = DefaultTriangulationOptions();

    // Local BA over the hierarchical association tree (paper Sect. III-D).
    HierarchicalAssociationTree::Options ba_tree = DefaultTreeOptions();
    // false: the same images in a plain local BA (k = 1, nothing fixed but
    // the images outside the tree), for the ablation.
    bool hierarchical_weights = true;
    // Local BA after each image: a few iterations from a good start converge
    // (the block was adjusted when its images registered).
    BundleAdjuster::Options ba = LocalBundleOptions();
    // Per point, at most this many observations from images held constant
    // (the fixed ripple and images outside the tree; 0: all). Video tracks
    // run over dozens of frames; a few fixed views pin a point as well.
    int ba_max_constant_observers = 2;
    // The global BA of Finish().
    BundleAdjuster::Options global_ba;

    // After each BA: observations farther than this from their projection are
    // dropped, then points seen under less than the angle.
    double filter_max_error_px = 4.0;
    double filter_min_tri_angle_deg = 1.5;

    // Unknown intrinsics: SIMPLE_RADIAL with the focal length from the
    // image's EXIF, else this many times the image's longer side (1.2: a
    // 45 deg field of view, typical of the normal lenses photogrammetry
    // uses); refined in every BA either way.
    double unknown_focal_factor = 1.2;

    // Finish() runs a global BA over everything.
    bool final_global_ba = true;

    bool Check() const;

    static BundleAdjuster::Options LocalBundleOptions();
    static SiftOptions DefaultSiftOptions();
    static HierarchicalAssociationTree::Options DefaultTreeOptions();
    static TriangulationOptions DefaultTriangulationOptions();
  };

  // `camera`: known intrinsics shared by all images (held fixed unless
  // options.ba refines them); without it each image size gets a camera with
  // a guessed focal length, refined in BA. `retrieval_model`: a trained model
  // file's content; without it retrieval bootstraps from the session.
  explicit Engine(const Options& options, std::optional<Camera> camera = std::nullopt,
                  std::shared_ptr<const RetrievalModel> retrieval_model = nullptr);

  // Decoding and feature extraction with `options`; thread-safe, so it may
  // run on another thread than the engine's.
  static PreparedFrame Prepare(const Frame& frame, const Options& options);

  // Processes one fly-in image. Returns its result first, then one for each
  // pending image that registered thanks to it. Its times include decoding
  // and features wherever they ran; `times.total` is their sum.
  std::vector<ImageResult> AddImage(const Frame& frame);
  std::vector<ImageResult> AddImage(PreparedFrame prepared);

  const Options& options() const { return options_; }

  // End of a batch: pending images get a last try, then the optional global
  // BA. Returns results for images registered by the last try.
  std::vector<ImageResult> Finish();

  const Reconstruction& reconstruction() const { return reconstruction_; }
  std::vector<std::string> PendingImageNames() const;
  int num_rejected() const { return num_rejected_; }
  bool initialized() const { return initialized_; }

 private:
  // What the engine keeps of each image it has seen.
  struct ImageState {
    FeatureSet features;
    cv::Mat grey;  // for LSM
    // How many registered verified neighbours it had at its last try.
    int registered_neighbours_at_last_try = -1;
  };
  // The outcome of two-view geometry for a pair, for initialisation.
  struct PairGeometry {
    image_t image_id1 = kInvalidImageId;
    image_t image_id2 = kInvalidImageId;
    TwoViewGeometry geometry;  // cam2_from_cam1
  };

  // The camera shared by the images of this size; created with the first
  // one (and its EXIF focal length, when intrinsics are unknown).
  camera_t CameraFor(int width, int height, std::optional<double> exif_focal_length_px);
  // `lsm_refined`: per keypoint of the new image, whether LSM has refined it
  // already (null: no LSM refinement). A keypoint is refined once, against
  // the first (most similar) candidate whose window it converges on; later
  // pairs keep its refined position.
  void MatchAndVerify(image_t image_id, image_t other_id, std::vector<char>* lsm_refined,
                      ImageResult* result);
  // The image's LSM pyramid (densification's levels; level 0 for refinement),
  // from the cache or built and cached. The levels share pixels with the
  // cache (cv::Mat), so the copy is cheap.
  std::vector<LsmImage> LsmPyramid(image_t image_id);
  bool TryInitialize(ImageResult* result);
  bool TryRegister(image_t image_id, ImageResult* result);
  std::vector<std::pair<point2D_t, point3D_t>> Find2D3DCorrespondences(image_t image_id);
  int Densify(image_t image_id, const Rigid3d& cam_from_world,
              std::vector<std::pair<point2D_t, point3D_t>>* correspondences);
  int Triangulate(image_t image_id);
  void AdjustAndFilter(image_t image_id, ImageResult* result);
  std::vector<int> RegisteredNeighbours(image_t image_id, int n) const;
  int NumRegisteredVerifiedNeighbours(image_t image_id) const;
  // Retries waiting images; results for those that register, except the new
  // image's, which goes into `new_image_result` (may be null).
  std::vector<ImageResult> RetryPending(ImageResult* new_image_result);
  void Finalize(ImageResult* result) const;

  Options options_;
  std::optional<Camera> known_camera_;
  Reconstruction reconstruction_;
  ImageRetriever retriever_;
  MatchStore matches_;
  std::unordered_map<image_t, ImageState> states_;
  struct CachedPyramid {
    std::vector<LsmImage> levels;
    std::list<image_t>::iterator recency;
    std::size_t bytes = 0;
  };
  std::unordered_map<image_t, CachedPyramid> lsm_pyramids_;
  std::list<image_t> lsm_recency_;  // most recently used first
  std::size_t lsm_cache_bytes_ = 0;
  std::vector<PairGeometry> pair_geometries_;
  std::vector<image_t> pending_;
  std::map<std::pair<int, int>, camera_t> camera_by_size_;
  bool initialized_ = false;
  int num_rejected_ = 0;
};

}  // namespace flysfm
