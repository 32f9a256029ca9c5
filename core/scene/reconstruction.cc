#include "core/scene/reconstruction.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <unordered_set>

#include "geometry/binary_io.h"
#include "geometry/check.h"

namespace flysfm {

camera_t Reconstruction::AddCamera(const Camera& camera, camera_t camera_id) {
  FLYSFM_CHECK(camera.IsValid());
  const camera_t id = camera_id != kInvalidCameraId ? camera_id
                      : cameras_.empty()           ? 1
                                                   : cameras_.rbegin()->first + 1;
  FLYSFM_CHECK(cameras_.emplace(id, camera).second);
  return id;
}

image_t Reconstruction::AddImage(const std::string& name, camera_t camera_id,
                                 const std::vector<Eigen::Vector2d>& keypoints,
                                 image_t image_id) {
  FLYSFM_CHECK(ExistsCamera(camera_id));
  const image_t id = image_id != kInvalidImageId ? image_id
                     : images_.empty()          ? 1
                                                : images_.rbegin()->first + 1;
  FLYSFM_CHECK(!ExistsImage(id));
  Image& image = images_[id];
  image.image_id = id;
  image.camera_id = camera_id;
  image.name = name;
  image.points2D.resize(keypoints.size());
  for (std::size_t i = 0; i < keypoints.size(); ++i) {
    image.points2D[i].xy = keypoints[i];
  }
  return id;
}

point2D_t Reconstruction::AddPoint2D(image_t image_id, const Eigen::Vector2d& xy) {
  Image& image = images_.at(image_id);
  image.points2D.push_back({xy, kInvalidPoint3DId});
  return point2D_t(image.points2D.size() - 1);
}

void Reconstruction::RegisterImage(image_t image_id, const Rigid3d& cam_from_world,
                                   model_t model_id) {
  FLYSFM_CHECK(model_id != kInvalidModelId);
  Image& image = images_.at(image_id);
  if (!image.IsRegistered()) registered_.push_back(image_id);
  FLYSFM_CHECK(image.num_points3D == 0 || image.model_id == model_id);
  image.cam_from_world = cam_from_world;
  image.model_id = model_id;
  changes_.changed_images.insert(image_id);
}

void Reconstruction::SetPose(image_t image_id, const Rigid3d& cam_from_world) {
  Image& image = images_.at(image_id);
  FLYSFM_CHECK(image.IsRegistered());
  image.cam_from_world = cam_from_world;
  changes_.changed_images.insert(image_id);
}

void Reconstruction::DeRegisterImage(image_t image_id) {
  Image& image = images_.at(image_id);
  for (point2D_t idx = 0; idx < image.points2D.size(); ++idx) {
    if (image.points2D[idx].HasPoint3D()) DeleteObservation(image_id, idx);
  }
  image.cam_from_world.reset();
  image.model_id = kInvalidModelId;
  changes_.changed_images.insert(image_id);
  registered_.erase(std::remove(registered_.begin(), registered_.end(), image_id),
                    registered_.end());
}

point3D_t Reconstruction::AddPoint3D(const Eigen::Vector3d& xyz,
                                     const std::vector<TrackElement>& track,
                                     const std::array<std::uint8_t, 3>& color,
                                     point3D_t point3D_id) {
  const point3D_t id =
      point3D_id != kInvalidPoint3DId ? point3D_id : next_point3D_id_;
  FLYSFM_CHECK(!ExistsPoint3D(id));
  next_point3D_id_ = std::max(next_point3D_id_, id + 1);
  Point3D& point = points3D_[id];
  point.xyz = xyz;
  point.color = color;
  changes_.removed_points.erase(id);
  changes_.added_points.insert(id);
  for (const TrackElement& element : track) AddObservation(id, element);
  return id;
}

void Reconstruction::AddObservation(point3D_t point3D_id,
                                    const TrackElement& element) {
  Image& image = images_.at(element.image_id);
  FLYSFM_CHECK(image.IsRegistered());
  Point2D& point2D = image.points2D.at(element.point2D_idx);
  FLYSFM_CHECK(!point2D.HasPoint3D());
  Point3D& point = points3D_.at(point3D_id);
  FLYSFM_CHECK(point.track.empty() || ModelOfPoint(point3D_id) == image.model_id);
  point2D.point3D_id = point3D_id;
  ++image.num_points3D;
  point.track.push_back(element);
  MarkPointChanged(point3D_id);
}

void Reconstruction::DeleteObservation(image_t image_id, point2D_t point2D_idx) {
  Image& image = images_.at(image_id);
  Point2D& point2D = image.points2D.at(point2D_idx);
  FLYSFM_CHECK(point2D.HasPoint3D());
  const point3D_t point3D_id = point2D.point3D_id;
  point2D.point3D_id = kInvalidPoint3DId;
  --image.num_points3D;
  std::vector<TrackElement>& track = points3D_.at(point3D_id).track;
  track.erase(std::remove(track.begin(), track.end(),
                          TrackElement{image_id, point2D_idx}),
              track.end());
  if (track.size() < 2) {
    DeletePoint3D(point3D_id);
  } else {
    MarkPointChanged(point3D_id);
  }
}

void Reconstruction::DeletePoint3D(point3D_t point3D_id) {
  for (const TrackElement& element : points3D_.at(point3D_id).track) {
    Image& image = images_.at(element.image_id);
    image.points2D.at(element.point2D_idx).point3D_id = kInvalidPoint3DId;
    --image.num_points3D;
  }
  points3D_.erase(point3D_id);
  changes_.changed_points.erase(point3D_id);
  // A point added and removed between two takes was never seen outside.
  if (changes_.added_points.erase(point3D_id) == 0) {
    changes_.removed_points.insert(point3D_id);
  }
}

void Reconstruction::MarkPointChanged(point3D_t point3D_id) {
  if (changes_.added_points.count(point3D_id) == 0) {
    changes_.changed_points.insert(point3D_id);
  }
}

void Reconstruction::Changes::Merge(const Changes& later) {
  // The same rules as the model's own marks: added wins over changed, and
  // removing an added point forgets it.
  for (const point3D_t id : later.removed_points) {
    changed_points.erase(id);
    if (added_points.erase(id) == 0) removed_points.insert(id);
  }
  for (const point3D_t id : later.added_points) {
    removed_points.erase(id);
    added_points.insert(id);
  }
  for (const point3D_t id : later.changed_points) {
    if (added_points.count(id) == 0) changed_points.insert(id);
  }
  changed_images.insert(later.changed_images.begin(), later.changed_images.end());
  changed_cameras = changed_cameras || later.changed_cameras;
}

Reconstruction::Changes Reconstruction::TakeChanges() {
  Changes taken = std::move(changes_);
  changes_ = Changes();
  return taken;
}

point3D_t Reconstruction::MergePoints3D(point3D_t point3D_id1,
                                        point3D_t point3D_id2) {
  FLYSFM_CHECK(point3D_id1 != point3D_id2);
  FLYSFM_CHECK(ModelOfPoint(point3D_id1) == ModelOfPoint(point3D_id2));
  Point3D& keep = points3D_.at(point3D_id1);
  const Point3D gone = points3D_.at(point3D_id2);
  const double n1 = keep.track.size();
  const double n2 = gone.track.size();
  keep.xyz = (n1 * keep.xyz + n2 * gone.xyz) / (n1 + n2);
  MarkPointChanged(point3D_id1);
  DeletePoint3D(point3D_id2);
  for (const TrackElement& element : gone.track) {
    const bool image_seen = std::any_of(
        keep.track.begin(), keep.track.end(),
        [&](const TrackElement& e) { return e.image_id == element.image_id; });
    if (!image_seen) AddObservation(point3D_id1, element);
  }
  return point3D_id1;
}

model_t Reconstruction::NewModelId() const {
  model_t largest = kFirstModelId - 1;
  for (const image_t image_id : registered_) {
    largest = std::max(largest, images_.at(image_id).model_id);
  }
  return largest + 1;
}

model_t Reconstruction::ModelOfPoint(point3D_t point3D_id) const {
  const Point3D& point = points3D_.at(point3D_id);
  FLYSFM_CHECK(!point.track.empty());
  return images_.at(point.track.front().image_id).model_id;
}

std::vector<std::pair<model_t, std::vector<image_t>>> Reconstruction::Models() const {
  std::vector<std::pair<model_t, std::vector<image_t>>> models;
  std::map<model_t, std::size_t> index;
  for (const image_t image_id : registered_) {
    const model_t model_id = images_.at(image_id).model_id;
    const auto [it, added] = index.emplace(model_id, models.size());
    if (added) models.push_back({model_id, {}});
    models[it->second].second.push_back(image_id);
  }
  std::stable_sort(models.begin(), models.end(), [](const auto& a, const auto& b) {
    return a.second.size() > b.second.size();
  });
  return models;
}

Reconstruction Reconstruction::SubModel(model_t model_id) const {
  Reconstruction copy = *this;
  for (const image_t image_id : registered_) {
    if (images_.at(image_id).model_id != model_id) copy.DeRegisterImage(image_id);
  }
  copy.changes_ = Changes();
  return copy;
}

void Reconstruction::MergeModels(model_t source_id, model_t target_id,
                                 const Sim3d& target_from_source) {
  FLYSFM_CHECK(source_id != target_id && target_id != kInvalidModelId);
  std::unordered_set<point3D_t> points;
  for (const image_t image_id : registered_) {
    Image& image = images_.at(image_id);
    if (image.model_id != source_id) continue;
    image.cam_from_world = TransformPose(target_from_source, *image.cam_from_world);
    image.linear_velocity *= target_from_source.scale;
    image.model_id = target_id;
    changes_.changed_images.insert(image_id);
    for (const Point2D& point2D : image.points2D) {
      if (point2D.HasPoint3D()) points.insert(point2D.point3D_id);
    }
  }
  for (const point3D_t point3D_id : points) {
    Point3D& point = points3D_.at(point3D_id);
    point.xyz = target_from_source * point.xyz;
    MarkPointChanged(point3D_id);
  }
}

std::size_t Reconstruction::NumObservations() const {
  std::size_t count = 0;
  for (const auto& [id, point] : points3D_) count += point.track.size();
  return count;
}

std::size_t Reconstruction::NumSharedPoints3D(image_t image_id1, image_t image_id2) const {
  std::vector<point3D_t> observed;
  for (const Point2D& point2D : images_.at(image_id1).points2D) {
    if (point2D.HasPoint3D()) observed.push_back(point2D.point3D_id);
  }
  std::sort(observed.begin(), observed.end());
  std::size_t shared = 0;
  for (const Point2D& point2D : images_.at(image_id2).points2D) {
    shared += point2D.HasPoint3D() &&
              std::binary_search(observed.begin(), observed.end(), point2D.point3D_id);
  }
  return shared;
}

double Reconstruction::ReprojectionError(image_t image_id, point2D_t point2D_idx,
                                         const Eigen::Vector3d& xyz) const {
  const Image& image = images_.at(image_id);
  FLYSFM_CHECK(image.IsRegistered());
  const Camera& camera = cameras_.at(image.camera_id);
  const Eigen::Vector2d& xy = image.points2D.at(point2D_idx).xy;
  const Eigen::Vector3d in_cam = camera.InCamAtRow(
      *image.cam_from_world * xyz, xy.y(), image.angular_velocity, image.linear_velocity);
  if (in_cam.z() <= std::numeric_limits<double>::epsilon()) {
    return std::numeric_limits<double>::infinity();
  }
  return (camera.ImgFromCam(in_cam) - xy).norm();
}

double Reconstruction::TriangulationAngleDeg(point3D_t point3D_id) const {
  const Point3D& point = points3D_.at(point3D_id);
  std::vector<Eigen::Vector3d> rays;
  rays.reserve(point.track.size());
  for (const TrackElement& element : point.track) {
    const Image& image = images_.at(element.image_id);
    rays.push_back((point.xyz - ProjectionCenter(*image.cam_from_world)).normalized());
  }
  double min_cos = 1.0;
  for (std::size_t i = 0; i < rays.size(); ++i) {
    for (std::size_t j = i + 1; j < rays.size(); ++j) {
      min_cos = std::min(min_cos, rays[i].dot(rays[j]));
    }
  }
  return std::acos(std::clamp(min_cos, -1.0, 1.0)) * 180.0 / M_PI;
}

std::size_t Reconstruction::FilterPoints3D(const std::vector<point3D_t>& point3D_ids,
                                           double max_error_px,
                                           double min_angle_deg) {
  return FilterPoints3D(
      point3D_ids, [max_error_px](image_t) { return max_error_px; }, min_angle_deg);
}

std::size_t Reconstruction::FilterPoints3D(const std::vector<point3D_t>& point3D_ids,
                                           const std::function<double(image_t)>& max_error_px,
                                           double min_angle_deg) {
  std::size_t removed = 0;
  for (const point3D_t id : point3D_ids) {
    if (!ExistsPoint3D(id)) continue;
    // A copy: deleting observations edits the track, and a track left with
    // one element deletes the whole point.
    const Point3D point = points3D_.at(id);
    for (const TrackElement& element : point.track) {
      if (!ExistsPoint3D(id)) break;
      if (ReprojectionError(element.image_id, element.point2D_idx, point.xyz) >
          max_error_px(element.image_id)) {
        DeleteObservation(element.image_id, element.point2D_idx);
      }
    }
    if (ExistsPoint3D(id) && TriangulationAngleDeg(id) < min_angle_deg) {
      DeletePoint3D(id);
    }
    removed += point.track.size() -
               (ExistsPoint3D(id) ? points3D_.at(id).track.size() : 0);
  }
  return removed;
}

std::vector<point3D_t> Reconstruction::Point3DIds() const {
  std::vector<point3D_t> ids;
  ids.reserve(points3D_.size());
  for (const auto& [id, point] : points3D_) ids.push_back(id);
  return ids;
}

std::size_t Reconstruction::FilterAllPoints3D(double max_error_px,
                                              double min_angle_deg) {
  return FilterPoints3D(Point3DIds(), max_error_px, min_angle_deg);
}

std::size_t Reconstruction::FilterPoints3D(
    const std::vector<point3D_t>& point3D_ids,
    const std::unordered_map<image_t, double>& max_error_px, double min_angle_deg) {
  return FilterPoints3D(
      point3D_ids,
      [&max_error_px](image_t image_id) {
        const auto bound = max_error_px.find(image_id);
        return bound == max_error_px.end() ? std::numeric_limits<double>::infinity()
                                           : bound->second;
      },
      min_angle_deg);
}

void Reconstruction::UpdatePointErrors() {
  for (auto& [id, point] : points3D_) {
    double sum = 0;
    for (const TrackElement& element : point.track) {
      sum += ReprojectionError(element.image_id, element.point2D_idx, point.xyz);
    }
    point.error = point.track.empty() ? -1.0 : sum / point.track.size();
  }
}

double Reconstruction::MeanReprojectionError() const {
  double sum = 0;
  std::size_t count = 0;
  for (const auto& [id, point] : points3D_) {
    for (const TrackElement& element : point.track) {
      sum += ReprojectionError(element.image_id, element.point2D_idx, point.xyz);
      ++count;
    }
  }
  return count == 0 ? 0.0 : sum / count;
}

double Reconstruction::MeanTrackLength() const {
  return points3D_.empty() ? 0.0 : double(NumObservations()) / points3D_.size();
}

void Reconstruction::Transform(const Sim3d& new_from_old) {
  for (auto& [id, image] : images_) {
    if (image.IsRegistered()) {
      image.cam_from_world = TransformPose(new_from_old, *image.cam_from_world);
      changes_.changed_images.insert(id);
    }
    // A camera's own frame turns with it; its distances scale.
    image.linear_velocity *= new_from_old.scale;
  }
  for (auto& [id, point] : points3D_) {
    point.xyz = new_from_old * point.xyz;
    MarkPointChanged(id);
  }
}

namespace {

constexpr char kReconstructionMagic[9] = "FSMODEL1";
// 2: a camera's readout time, an image's capture time and motion.
// 3: a registered image's sub-model.
constexpr std::uint32_t kReconstructionVersion = 3;

struct StoredPoint2D {
  double x;
  double y;
};

[[noreturn]] void Corrupt(const std::string& what) {
  throw std::runtime_error("corrupt model in the checkpoint: " + what);
}

}  // namespace

void Reconstruction::Write(std::ostream& out) const {
  WriteHeader(out, kReconstructionMagic, kReconstructionVersion);
  WriteCount(out, cameras_.size());
  for (const auto& [camera_id, camera] : cameras_) {
    WriteValue(out, camera_id);
    WriteValue(out, int(camera.model_id));
    WriteValue(out, camera.width);
    WriteValue(out, camera.height);
    WriteVector(out, camera.params);
    WriteValue(out, camera.readout_time);
  }
  WriteCount(out, images_.size());
  std::vector<StoredPoint2D> xy;
  for (const auto& [image_id, image] : images_) {
    WriteValue(out, image_id);
    WriteValue(out, image.camera_id);
    WriteString(out, image.name);
    WriteValue(out, std::uint8_t(image.IsRegistered()));
    if (image.IsRegistered()) {
      WriteRigid3d(out, *image.cam_from_world);
      WriteValue(out, image.model_id);
    }
    WriteValue(out, std::uint8_t(image.capture_time.has_value()));
    if (image.capture_time) WriteValue(out, *image.capture_time);
    WriteValue(out, std::array<double, 6>{
                        image.angular_velocity.x(), image.angular_velocity.y(),
                        image.angular_velocity.z(), image.linear_velocity.x(),
                        image.linear_velocity.y(), image.linear_velocity.z()});
    xy.clear();
    for (const Point2D& point2D : image.points2D) xy.push_back({point2D.xy.x(), point2D.xy.y()});
    WriteVector(out, xy);
  }
  WriteVector(out, registered_);
  WriteValue(out, next_point3D_id_);
  WriteCount(out, points3D_.size());
  for (const auto& [point3D_id, point] : points3D_) {
    WriteValue(out, point3D_id);
    WriteValue(out, std::array<double, 3>{point.xyz.x(), point.xyz.y(), point.xyz.z()});
    WriteValue(out, point.color);
    WriteValue(out, point.error);
    WriteVector(out, point.track);
  }
}

Reconstruction Reconstruction::Read(std::istream& in) {
  ReadHeader(in, kReconstructionMagic, kReconstructionVersion);
  Reconstruction model;
  const std::size_t num_cameras = ReadCount(in, "cameras", 1 << 20);
  for (std::size_t i = 0; i < num_cameras; ++i) {
    const auto camera_id = ReadValue<camera_t>(in, "camera id");
    Camera camera;
    camera.model_id = CameraModelId(ReadValue<int>(in, "camera model"));
    camera.width = ReadValue<int>(in, "camera width");
    camera.height = ReadValue<int>(in, "camera height");
    camera.params = ReadVector<double>(in, "camera parameters", 64);
    camera.readout_time = ReadValue<double>(in, "camera readout time");
    if (!camera.IsValid() || !std::isfinite(camera.readout_time) ||
        !model.cameras_.emplace(camera_id, camera).second) {
      Corrupt("camera " + std::to_string(camera_id));
    }
  }
  const std::size_t num_images = ReadCount(in, "images", 1 << 24);
  for (std::size_t i = 0; i < num_images; ++i) {
    const auto image_id = ReadValue<image_t>(in, "image id");
    Image& image = model.images_[image_id];
    if (image.image_id != kInvalidImageId || image_id == kInvalidImageId) {
      Corrupt("image id " + std::to_string(image_id));
    }
    image.image_id = image_id;
    image.camera_id = ReadValue<camera_t>(in, "image camera");
    if (!model.ExistsCamera(image.camera_id)) {
      Corrupt("camera of image " + std::to_string(image_id));
    }
    image.name = ReadString(in, "image name");
    if (ReadValue<std::uint8_t>(in, "image registration")) {
      image.cam_from_world = ReadRigid3d(in, "image pose");
      image.model_id = ReadValue<model_t>(in, "image sub-model");
      if (image.model_id == kInvalidModelId) {
        Corrupt("sub-model of image " + std::to_string(image_id));
      }
    }
    if (ReadValue<std::uint8_t>(in, "image capture time flag")) {
      image.capture_time = ReadValue<double>(in, "image capture time");
      if (!std::isfinite(*image.capture_time)) {
        Corrupt("capture time of image " + std::to_string(image_id));
      }
    }
    const auto motion = ReadValue<std::array<double, 6>>(in, "image motion");
    image.angular_velocity = Eigen::Vector3d(motion[0], motion[1], motion[2]);
    image.linear_velocity = Eigen::Vector3d(motion[3], motion[4], motion[5]);
    if (!image.angular_velocity.allFinite() || !image.linear_velocity.allFinite()) {
      Corrupt("motion of image " + std::to_string(image_id));
    }
    for (const StoredPoint2D& xy : ReadVector<StoredPoint2D>(in, "keypoints")) {
      image.points2D.push_back({Eigen::Vector2d(xy.x, xy.y), kInvalidPoint3DId});
    }
  }
  model.registered_ = ReadVector<image_t>(in, "registered images", num_images);
  std::size_t num_registered = 0;
  for (const auto& [image_id, image] : model.images_) num_registered += image.IsRegistered();
  for (const image_t image_id : model.registered_) {
    if (!model.ExistsImage(image_id) || !model.image(image_id).IsRegistered()) {
      Corrupt("registered image " + std::to_string(image_id));
    }
  }
  if (num_registered != model.registered_.size()) Corrupt("the registered images' order");
  model.next_point3D_id_ = ReadValue<point3D_t>(in, "next point id");
  const std::size_t num_points = ReadCount(in, "points", std::size_t(1) << 30);
  model.points3D_.reserve(num_points);
  for (std::size_t i = 0; i < num_points; ++i) {
    const auto point3D_id = ReadValue<point3D_t>(in, "point id");
    if (point3D_id == kInvalidPoint3DId || point3D_id >= model.next_point3D_id_ ||
        model.ExistsPoint3D(point3D_id)) {
      Corrupt("point id " + std::to_string(point3D_id));
    }
    Point3D& point = model.points3D_[point3D_id];
    const auto xyz = ReadValue<std::array<double, 3>>(in, "point position");
    point.xyz = Eigen::Vector3d(xyz[0], xyz[1], xyz[2]);
    point.color = ReadValue<std::array<std::uint8_t, 3>>(in, "point colour");
    point.error = ReadValue<double>(in, "point error");
    point.track = ReadVector<TrackElement>(in, "track", num_images);
    if (point.track.size() < 2) Corrupt("track of point " + std::to_string(point3D_id));
    model_t model_id = kInvalidModelId;
    for (const TrackElement& element : point.track) {
      const auto image = model.images_.find(element.image_id);
      if (image == model.images_.end() || !image->second.IsRegistered() ||
          element.point2D_idx >= image->second.points2D.size() ||
          image->second.points2D[element.point2D_idx].HasPoint3D() ||
          (model_id != kInvalidModelId && image->second.model_id != model_id)) {
        Corrupt("track of point " + std::to_string(point3D_id));
      }
      model_id = image->second.model_id;
      image->second.points2D[element.point2D_idx].point3D_id = point3D_id;
      ++image->second.num_points3D;
    }
  }
  return model;
}

}  // namespace flysfm
