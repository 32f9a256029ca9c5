#pragma once

// What the live web view shows, apart from the HTTP that carries it: the
// update one processed image makes (built from the model's changes, so its
// size follows what the image changed, not the model), the view's own copy
// of the model (kept current by those updates, so that a page connecting
// mid-run is served without touching the engine's model), and the JSON
// messages of the push protocol (docs/view.md).

#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <unordered_map>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "core/scene/image_result.h"
#include "core/scene/reconstruction.h"
#include "quality/coverage.h"
#include "quality/quality_tracker.h"

namespace flysfm {

// One registered image drawn as a frustum.
struct ViewCamera {
  image_t image_id = kInvalidImageId;
  camera_t camera_id = kInvalidCameraId;
  std::string name;
  // The sub-model it is registered in: the page colours each apart.
  model_t model_id = kInvalidModelId;
  // World to camera, as the model stores it.
  Eigen::Quaterniond rotation = Eigen::Quaterniond::Identity();
  Eigen::Vector3d translation = Eigen::Vector3d::Zero();
};

// A camera's intrinsics as far as a frustum needs them.
struct ViewIntrinsics {
  camera_t camera_id = kInvalidCameraId;
  double focal = 0;
  int width = 0;
  int height = 0;
};

// The per-image line, as the terminal prints it.
struct ViewLine {
  std::string name;
  std::string status;  // ImageStatusName
  std::string reason;
  int points = 0;
  int new_points = 0;
  double ms = 0;
  std::optional<double> delay_ms;  // from the shot's arrival (live runs)
  // The tag of the photographer's source (several sources); else empty.
  std::string source;
  // While there are several sub-models, or when the shot merged some: which
  // one it is in and what it merged ("sub-model 2 of 3", "merged 1").
  std::string model;
};
ViewLine MakeViewLine(const ImageResult& result, std::optional<double> delay_ms,
                      const std::string& source = "");

// The quality measures the page colours points by (docs/quality.md), one
// entry per point of the update or snapshot, in the same order; empty when
// the run measures none.
struct ViewPointQuality {
  std::vector<std::uint16_t> views;     // observing images, at most 65535
  std::vector<float> max_angle_deg;     // largest triangulation angle
  std::vector<float> sigma;             // positional uncertainty; NaN: undefined
  bool empty() const { return views.empty(); }
};

// What "well covered" means for the page's coverage colouring and share: the
// tracker's options, sent along so that page and summary.json agree.
struct ViewCoverageRule {
  int min_views = 0;
  double min_angle_deg = 0;
};

// The coverage surface and the suggested viewpoints (quality/coverage.h), as
// the page draws them: each face's corners and class, each suggestion a
// ghost camera with its reason.
struct ViewSurface {
  std::vector<float> xyz;                // 9 per face
  std::vector<std::uint8_t> classes;     // Coverage::FaceClass, one per face
  double well_covered_share = 0;         // of the reachable area
  double area = 0;
  struct Suggestion {
    Eigen::Quaterniond rotation = Eigen::Quaterniond::Identity();  // cam_from_world
    Eigen::Vector3d translation = Eigen::Vector3d::Zero();
    double area_share = 0;
    std::string reason;
  };
  std::vector<Suggestion> suggestions;
};
ViewSurface MakeViewSurface(const Coverage& coverage);

// What one step of the engine changed, as the page needs it.
struct ViewUpdate {
  std::vector<ViewLine> lines;
  std::vector<ViewCamera> cameras;        // newly registered or moved
  std::vector<image_t> removed_cameras;   // deregistered
  std::vector<ViewIntrinsics> intrinsics; // every camera, when any was refined
  // Points added or moved: ids, xyz (3 per point), rgb (3 per point).
  std::vector<point3D_t> point_ids;
  std::vector<float> xyz;
  std::vector<std::uint8_t> rgb;
  // The points' measures, when the run has a quality tracker.
  ViewPointQuality quality;
  std::optional<ViewCoverageRule> coverage_rule;
  // The surface, when it was measured again since the last update.
  std::optional<ViewSurface> surface;
  std::vector<point3D_t> removed_points;
  int num_images = 0;
  int num_points = 0;
};

// The update for `changes` (Reconstruction::TakeChanges) of `model`, with the
// lines of the images this step reported. Its cost is that of the changes.
// With `quality` (brought up to date with the same changes), the points carry
// their measures. With `surface`, the update carries it (the run loop gives
// it when it was measured again).
ViewUpdate MakeViewUpdate(const Reconstruction& model, const Reconstruction::Changes& changes,
                          std::vector<ViewLine> lines, const QualityTracker* quality = nullptr,
                          const Coverage* surface = nullptr);
// The whole of `model` as one update: what `flysfm view` serves, and what a
// run that starts from a resumed model begins with.
ViewUpdate MakeFullViewUpdate(const Reconstruction& model,
                              const QualityTracker* quality = nullptr,
                              const Coverage* surface = nullptr);

// The view's copy of the model, without its index: what a `model` message is
// written from. Copying it is copying flat arrays.
struct ViewSnapshot {
  std::vector<point3D_t> point_ids;
  std::vector<float> xyz;
  std::vector<std::uint8_t> rgb;
  ViewPointQuality quality;  // every point's, once an update carried them
  std::optional<ViewCoverageRule> coverage_rule;
  std::optional<ViewSurface> surface;  // the latest
  std::map<image_t, ViewCamera> cameras;
  std::map<camera_t, ViewIntrinsics> intrinsics;
  // Image name -> why it waits / why it was rejected.
  std::map<std::string, std::string> pending;
  std::map<std::string, std::string> rejected;
  std::optional<ViewLine> latest;
  int num_images = 0;
  int num_points = 0;
  bool finished = false;
};

// The snapshot plus the point id -> array slot index that makes an update's
// application O(changes): a removed point's slot is filled by the last one.
class ViewModel {
 public:
  // Returns whether the pending or rejected lists changed.
  bool Apply(const ViewUpdate& update);
  void Finish() { snapshot_.finished = true; }
  const ViewSnapshot& snapshot() const { return snapshot_; }

 private:
  // `i`: the point's entry in `update`.
  void SetPoint(const ViewUpdate& update, std::size_t i);
  void RemovePoint(point3D_t id);

  ViewSnapshot snapshot_;
  std::unordered_map<point3D_t, std::size_t> slot_;
};

// The push protocol's messages, one JSON object each, on one line (an SSE
// `data:` field may not hold a newline).
std::string ModelMessage(const ViewSnapshot& snapshot);
// `lists`: the pending and rejected lists to send along (they changed).
std::string UpdateMessage(const ViewUpdate& update, const ViewSnapshot* lists);
std::string EndMessage();
// What a long step of the run is doing (the end's adjustment, say), as the
// terminal's progress line tells it; empty: nothing to tell.
std::string StatusMessage(const std::string& text);

}  // namespace flysfm
