#pragma once

#include <functional>
#include <istream>
#include <map>
#include <ostream>
#include <set>
#include <string>
#include <unordered_map>
#include <vector>

#include <Eigen/Core>

#include "core/scene/image.h"
#include "core/scene/point3d.h"
#include "geometry/types.h"
#include "geometry/camera.h"
#include "geometry/sim3d.h"

namespace flysfm {

// The growing model: cameras, images (registered or waiting), 3D points and
// their tracks. It keeps the two directions of every observation consistent:
// a track element (image, point2D) <-> that Point2D's point3D_id.
class Reconstruction {
 public:
  // The Add* functions take the id to give (a model read from disk keeps its
  // ids) or, by default, the next free one. Ids start at 1, as in COLMAP.
  camera_t AddCamera(const Camera& camera, camera_t camera_id = kInvalidCameraId);
  // Adds an unregistered image with its keypoints (pixel coordinates).
  image_t AddImage(const std::string& name, camera_t camera_id,
                   const std::vector<Eigen::Vector2d>& keypoints,
                   image_t image_id = kInvalidImageId);
  // Appends a keypoint found after the image was added (LSM densification
  // finds observations where SIFT found none). Returns its index.
  point2D_t AddPoint2D(image_t image_id, const Eigen::Vector2d& xy);
  // Registered images fall into sub-models: blocks that no track joins, each
  // in a similarity frame of its own until MergeModels maps one into
  // another's (a chain of shots that broke, several photographers). A model
  // that never broke apart is the one sub-model kFirstModelId. A track's
  // observations all lie in one sub-model: AddObservation and MergePoints3D
  // check it.
  static constexpr model_t kFirstModelId = 1;
  // An image registered already keeps its sub-model unless it observes no
  // point.
  void RegisterImage(image_t image_id, const Rigid3d& cam_from_world,
                     model_t model_id = kFirstModelId);
  // Moves a registered image (an adjustment's result), in its sub-model.
  void SetPose(image_t image_id, const Rigid3d& cam_from_world);
  // Removes the pose and every observation the image has.
  void DeRegisterImage(image_t image_id);

  // The track's elements must be unobserved keypoints of distinct images.
  point3D_t AddPoint3D(const Eigen::Vector3d& xyz,
                       const std::vector<TrackElement>& track,
                       const std::array<std::uint8_t, 3>& color = {0, 0, 0},
                       point3D_t point3D_id = kInvalidPoint3DId);
  void AddObservation(point3D_t point3D_id, const TrackElement& element);
  // Removes one observation; a point left with fewer than two is deleted.
  void DeleteObservation(image_t image_id, point2D_t point2D_idx);
  void DeletePoint3D(point3D_t point3D_id);
  // Joins two points seen as the same: the position is the track-length
  // weighted mean; where both observe one image, the first's observation is
  // kept. Returns the surviving id.
  point3D_t MergePoints3D(point3D_t point3D_id1, point3D_t point3D_id2);

  bool ExistsCamera(camera_t id) const { return cameras_.count(id) > 0; }
  bool ExistsImage(image_t id) const { return images_.count(id) > 0; }
  bool ExistsPoint3D(point3D_t id) const { return points3D_.count(id) > 0; }
  const Camera& camera(camera_t id) const { return cameras_.at(id); }
  Camera& camera(camera_t id) { return cameras_.at(id); }
  const Image& image(image_t id) const { return images_.at(id); }
  Image& image(image_t id) { return images_.at(id); }
  const Point3D& point3D(point3D_t id) const { return points3D_.at(id); }
  Point3D& point3D(point3D_t id) { return points3D_.at(id); }
  const std::map<camera_t, Camera>& cameras() const { return cameras_; }
  const std::map<image_t, Image>& images() const { return images_; }
  const std::unordered_map<point3D_t, Point3D>& points3D() const { return points3D_; }
  // In the order the images were registered.
  const std::vector<image_t>& RegisteredImageIds() const { return registered_; }
  std::size_t NumRegisteredImages() const { return registered_.size(); }
  std::size_t NumPoints3D() const { return points3D_.size(); }
  std::size_t NumObservations() const;
  // A sub-model id that no registered image holds.
  model_t NewModelId() const;
  // The sub-model of a point: its observers'.
  model_t ModelOfPoint(point3D_t point3D_id) const;
  // Each sub-model's registered images in the order they registered; the
  // largest sub-model first (ties: the one registered first).
  std::vector<std::pair<model_t, std::vector<image_t>>> Models() const;
  // A copy holding only this sub-model registered (the other images stay,
  // unregistered), for writing each where a reader expects one model.
  Reconstruction SubModel(model_t model_id) const;
  // Maps the source sub-model's poses and points into the target's frame and
  // makes its images the target's. The tracks of the two stay apart: points
  // that are one are joined by MergePoints3D afterwards.
  void MergeModels(model_t source_id, model_t target_id, const Sim3d& target_from_source);
  // The 3D points both images observe (0 when either has none).
  std::size_t NumSharedPoints3D(image_t image_id1, image_t image_id2) const;

  // What changed since the last TakeChanges(), so that a consumer (the live
  // view) can follow the model at the cost of the change, not of the model.
  // A point id is in at most one of added / changed / removed: added wins
  // over changed, and removing an added point forgets it.
  struct Changes {
    std::set<point3D_t> added_points;
    std::set<point3D_t> changed_points;   // position, colour or track
    std::set<point3D_t> removed_points;
    std::set<image_t> changed_images;     // registered, pose moved, deregistered
    bool changed_cameras = false;         // some intrinsics were written
    bool empty() const {
      return added_points.empty() && changed_points.empty() && removed_points.empty() &&
             changed_images.empty() && !changed_cameras;
    }
    // Appends a later take, as if both had been one: a consumer that reads
    // less often than another takes (the live view beside the quality
    // tracker) keeps the takes it has not read yet this way.
    void Merge(const Changes& later);
  };
  Changes TakeChanges();
  // For writers outside this class (BA writes positions and intrinsics
  // through the non-const accessors).
  void MarkPointChanged(point3D_t point3D_id);
  void MarkCamerasChanged() { changes_.changed_cameras = true; }

  // Reprojection error in pixels of `xyz` against the keypoint; infinity when
  // the point lies behind the camera. The image must be registered.
  double ReprojectionError(image_t image_id, point2D_t point2D_idx,
                           const Eigen::Vector3d& xyz) const;
  // The largest angle, in degrees, between the rays from the track's camera
  // centres to the point.
  double TriangulationAngleDeg(point3D_t point3D_id) const;

  // Drops observations whose reprojection error exceeds `max_error_px`, then
  // points whose triangulation angle is below `min_angle_deg`. Only the given
  // points are looked at. Returns the number of observations removed.
  std::size_t FilterPoints3D(const std::vector<point3D_t>& point3D_ids,
                             double max_error_px, double min_angle_deg);
  std::size_t FilterAllPoints3D(double max_error_px, double min_angle_deg);
  // The same, each observation against its own image's bound (an image
  // without one: no bound).
  std::size_t FilterPoints3D(const std::vector<point3D_t>& point3D_ids,
                             const std::unordered_map<image_t, double>& max_error_px,
                             double min_angle_deg);
  // Recomputes Point3D::error for every point.
  void UpdatePointErrors();

  double MeanReprojectionError() const;
  double MeanTrackLength() const;

  // Maps the whole model (poses and points) by a similarity.
  void Transform(const Sim3d& new_from_old);

  // The whole model, its ids and order of registration included, in the
  // engine's checkpoint format. Read throws std::runtime_error on a
  // truncated or inconsistent stream.
  void Write(std::ostream& out) const;
  static Reconstruction Read(std::istream& in);

 private:
  std::size_t FilterPoints3D(const std::vector<point3D_t>& point3D_ids,
                             const std::function<double(image_t)>& max_error_px,
                             double min_angle_deg);
  std::vector<point3D_t> Point3DIds() const;

  std::map<camera_t, Camera> cameras_;
  std::map<image_t, Image> images_;
  std::unordered_map<point3D_t, Point3D> points3D_;
  std::vector<image_t> registered_;
  point3D_t next_point3D_id_ = 1;
  Changes changes_;
};

}  // namespace flysfm
