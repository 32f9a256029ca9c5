#include "io/view/view_model.h"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <limits>

#include <nlohmann/json.hpp>

namespace flysfm {
namespace {

ViewCamera MakeViewCamera(const Image& image) {
  ViewCamera camera;
  camera.image_id = image.image_id;
  camera.camera_id = image.camera_id;
  camera.name = image.name;
  camera.model_id = image.model_id;
  camera.rotation = image.cam_from_world->rotation;
  camera.translation = image.cam_from_world->translation;
  return camera;
}

std::vector<ViewIntrinsics> AllIntrinsics(const Reconstruction& model) {
  std::vector<ViewIntrinsics> all;
  for (const auto& [id, camera] : model.cameras()) {
    all.push_back({id, camera.MeanFocalLength(), camera.width, camera.height});
  }
  return all;
}

void AppendQuality(const PointQuality& measures, ViewPointQuality* quality) {
  quality->views.push_back(std::uint16_t(std::clamp(measures.views, 0, 65535)));
  quality->max_angle_deg.push_back(float(measures.max_angle_deg));
  quality->sigma.push_back(
      float(measures.sigma.value_or(std::numeric_limits<double>::quiet_NaN())));
}

void AppendPoint(const Reconstruction& model, point3D_t id, const QualityTracker* quality,
                 ViewUpdate* update) {
  const Point3D& point = model.point3D(id);
  update->point_ids.push_back(id);
  for (int k = 0; k < 3; ++k) {
    update->xyz.push_back(float(point.xyz[k]));
    update->rgb.push_back(point.color[k]);
  }
  if (!quality) return;
  const std::optional<PointQuality> measures = quality->Point(id);
  AppendQuality(measures ? *measures : PointQuality(), &update->quality);
}

std::optional<ViewCoverageRule> CoverageRule(const QualityTracker* quality) {
  if (!quality) return std::nullopt;
  return ViewCoverageRule{quality->options().min_views, quality->options().min_angle_deg};
}

// Numbers written by hand: a model message holds millions of them, and
// building a JSON tree for each would cost more than the message. Floats are
// written with a float's shortest round-trip digits, not a double's.
template <typename T>
void AppendNumber(T value, std::string* out) {
  if (!std::isfinite(value)) {
    *out += "null";  // JSON has no NaN; a page must not fail on one point
    return;
  }
  char buffer[32];
  const auto result = std::to_chars(buffer, buffer + sizeof(buffer), value);
  out->append(buffer, result.ptr);
}

template <typename T>
void AppendIntegers(const char* key, const std::vector<T>& values, std::string* out) {
  *out += '"';
  *out += key;
  *out += "\":[";
  char buffer[24];
  for (std::size_t i = 0; i < values.size(); ++i) {
    if (i > 0) *out += ',';
    const auto result = std::to_chars(buffer, buffer + sizeof(buffer), values[i]);
    out->append(buffer, result.ptr);
  }
  *out += ']';
}

void AppendFloats(const char* key, const std::vector<float>& values, std::string* out) {
  *out += '"';
  *out += key;
  *out += "\":[";
  for (std::size_t i = 0; i < values.size(); ++i) {
    if (i > 0) *out += ',';
    AppendNumber(values[i], out);
  }
  *out += ']';
}

// "points":{"ids":[...],"xyz":[...],"rgb":[...]}, as model and update
// messages both carry them, with "views", "angle" and "sigma" (null:
// undefined) when the points were measured.
template <typename Id, typename Colour>
void AppendPoints(const std::vector<Id>& ids, const std::vector<float>& xyz,
                  const std::vector<Colour>& rgb, const ViewPointQuality& quality,
                  std::string* out) {
  *out += "\"points\":{";
  AppendIntegers("ids", ids, out);
  *out += ',';
  AppendFloats("xyz", xyz, out);
  *out += ',';
  AppendIntegers("rgb", rgb, out);
  if (!quality.empty()) {
    *out += ',';
    AppendIntegers("views", quality.views, out);
    *out += ',';
    AppendFloats("angle", quality.max_angle_deg, out);
    *out += ',';
    AppendFloats("sigma", quality.sigma, out);
  }
  *out += '}';
}

// "coverage":{"min_views":3,"min_angle_deg":10}, when the points are measured.
void AppendCoverageRule(const std::optional<ViewCoverageRule>& rule, std::string* out) {
  if (!rule) return;
  *out += ",\"coverage\":{\"min_views\":" + std::to_string(rule->min_views) +
          ",\"min_angle_deg\":";
  AppendNumber(rule->min_angle_deg, out);
  *out += '}';
}


void AppendString(const std::string& value, std::string* out) {
  // nlohmann's escaping; invalid UTF-8 in a file name is replaced, not thrown.
  *out += nlohmann::json(value).dump(-1, ' ', false, nlohmann::json::error_handler_t::replace);
}

// "q":[x,y,z,w],"t":[x,y,z]: a cam_from_world, the rotation as three.js's
// Quaternion takes it.
void AppendPose(const Eigen::Quaterniond& rotation, const Eigen::Vector3d& translation,
                std::string* out) {
  *out += "\"q\":[";
  const double q[4] = {rotation.x(), rotation.y(), rotation.z(), rotation.w()};
  for (int k = 0; k < 4; ++k) {
    if (k > 0) *out += ',';
    AppendNumber(q[k], out);
  }
  *out += "],\"t\":[";
  for (int k = 0; k < 3; ++k) {
    if (k > 0) *out += ',';
    AppendNumber(translation[k], out);
  }
  *out += ']';
}

// "surface":{"share":..,"area":..,"xyz":[...],"classes":[...],
// "suggestions":[{"q":[x,y,z,w],"t":[...],"share":..,"reason":".."}]}.
void AppendSurface(const std::optional<ViewSurface>& surface, std::string* out) {
  if (!surface) return;
  *out += ",\"surface\":{\"share\":";
  AppendNumber(surface->well_covered_share, out);
  *out += ",\"area\":";
  AppendNumber(surface->area, out);
  *out += ',';
  AppendFloats("xyz", surface->xyz, out);
  *out += ',';
  AppendIntegers("classes", surface->classes, out);
  *out += ",\"suggestions\":[";
  for (std::size_t i = 0; i < surface->suggestions.size(); ++i) {
    const ViewSurface::Suggestion& s = surface->suggestions[i];
    if (i > 0) *out += ',';
    *out += '{';
    AppendPose(s.rotation, s.translation, out);
    *out += ",\"share\":";
    AppendNumber(s.area_share, out);
    *out += ",\"reason\":";
    AppendString(s.reason, out);
    *out += '}';
  }
  *out += "]}";
}

void AppendCameras(const std::vector<const ViewCamera*>& cameras, std::string* out) {
  *out += "\"cameras\":[";
  for (std::size_t i = 0; i < cameras.size(); ++i) {
    const ViewCamera& c = *cameras[i];
    if (i > 0) *out += ',';
    *out += "{\"id\":" + std::to_string(c.image_id) +
            ",\"camera_id\":" + std::to_string(c.camera_id) +
            ",\"model\":" + std::to_string(c.model_id) + ",\"name\":";
    AppendString(c.name, out);
    *out += ',';
    AppendPose(c.rotation, c.translation, out);
    *out += '}';
  }
  *out += ']';
}

void AppendIntrinsics(const std::vector<ViewIntrinsics>& intrinsics, std::string* out) {
  *out += "\"intrinsics\":[";
  for (std::size_t i = 0; i < intrinsics.size(); ++i) {
    const ViewIntrinsics& k = intrinsics[i];
    if (i > 0) *out += ',';
    *out += "{\"camera_id\":" + std::to_string(k.camera_id) + ",\"focal\":";
    AppendNumber(k.focal, out);
    *out += ",\"width\":" + std::to_string(k.width) +
            ",\"height\":" + std::to_string(k.height) + "}";
  }
  *out += ']';
}

void AppendLine(const ViewLine& line, std::string* out) {
  *out += "{\"name\":";
  AppendString(line.name, out);
  *out += ",\"status\":";
  AppendString(line.status, out);
  *out += ",\"reason\":";
  AppendString(line.reason, out);
  *out += ",\"points\":" + std::to_string(line.points) +
          ",\"new_points\":" + std::to_string(line.new_points) + ",\"ms\":";
  AppendNumber(line.ms, out);
  *out += ",\"delay_ms\":";
  if (line.delay_ms) {
    AppendNumber(*line.delay_ms, out);
  } else {
    *out += "null";
  }
  *out += ",\"source\":";
  AppendString(line.source, out);
  *out += ",\"model\":";
  AppendString(line.model, out);
  *out += '}';
}

void AppendNamedReasons(const char* key, const std::map<std::string, std::string>& reasons,
                        std::string* out) {
  *out += '"';
  *out += key;
  *out += "\":[";
  bool first = true;
  for (const auto& [name, reason] : reasons) {
    if (!first) *out += ',';
    first = false;
    *out += "{\"name\":";
    AppendString(name, out);
    *out += ",\"reason\":";
    AppendString(reason, out);
    *out += '}';
  }
  *out += ']';
}

void AppendCounts(int num_images, int num_points, std::string* out) {
  *out += "\"counts\":{\"images\":" + std::to_string(num_images) +
          ",\"points\":" + std::to_string(num_points) + "}";
}

}  // namespace

ViewLine MakeViewLine(const ImageResult& result, std::optional<double> delay_ms,
                      const std::string& source) {
  ViewLine line;
  line.source = source;
  line.name = result.name;
  line.status = ImageStatusName(result.status);
  line.reason = result.reason;
  line.points = result.num_observations;
  line.new_points = result.num_new_points;
  line.ms = result.times.total;
  line.delay_ms = delay_ms;
  if (result.num_models > 1 && result.model_id != kInvalidModelId) {
    line.model = "sub-model " + std::to_string(result.model_id) + " of " +
                 std::to_string(result.num_models);
  }
  if (result.num_merged_models > 0) {
    line.model += (line.model.empty() ? "" : ", ") + std::string("merged ") +
                  std::to_string(result.num_merged_models);
  }
  return line;
}

ViewSurface MakeViewSurface(const Coverage& coverage) {
  ViewSurface surface;
  surface.xyz.reserve(9 * coverage.faces().size());
  surface.classes.reserve(coverage.faces().size());
  for (const Coverage::Face& face : coverage.faces()) {
    for (const Eigen::Vector3d& corner : face.corners) {
      for (int k = 0; k < 3; ++k) surface.xyz.push_back(float(corner[k]));
    }
    surface.classes.push_back(std::uint8_t(face.face_class));
  }
  surface.well_covered_share = coverage.summary().well_covered_share;
  surface.area = coverage.summary().area;
  for (const Coverage::Suggestion& suggestion : coverage.suggestions()) {
    surface.suggestions.push_back({suggestion.cam_from_world.rotation,
                                   suggestion.cam_from_world.translation,
                                   suggestion.area_share, suggestion.reason});
  }
  return surface;
}

ViewUpdate MakeViewUpdate(const Reconstruction& model, const Reconstruction::Changes& changes,
                          std::vector<ViewLine> lines, const QualityTracker* quality,
                          const Coverage* surface) {
  ViewUpdate update;
  if (surface) update.surface = MakeViewSurface(*surface);
  update.lines = std::move(lines);
  update.coverage_rule = CoverageRule(quality);
  for (const image_t id : changes.changed_images) {
    if (!model.ExistsImage(id)) continue;
    const Image& image = model.image(id);
    if (image.IsRegistered()) {
      update.cameras.push_back(MakeViewCamera(image));
    } else {
      update.removed_cameras.push_back(id);
    }
  }
  if (changes.changed_cameras) update.intrinsics = AllIntrinsics(model);
  const std::size_t num_points = changes.added_points.size() + changes.changed_points.size();
  update.point_ids.reserve(num_points);
  update.xyz.reserve(3 * num_points);
  update.rgb.reserve(3 * num_points);
  for (const point3D_t id : changes.added_points) AppendPoint(model, id, quality, &update);
  for (const point3D_t id : changes.changed_points) AppendPoint(model, id, quality, &update);
  update.removed_points.assign(changes.removed_points.begin(), changes.removed_points.end());
  update.num_images = int(model.NumRegisteredImages());
  update.num_points = int(model.NumPoints3D());
  return update;
}

ViewUpdate MakeFullViewUpdate(const Reconstruction& model, const QualityTracker* quality,
                              const Coverage* surface) {
  ViewUpdate update;
  if (surface) update.surface = MakeViewSurface(*surface);
  update.coverage_rule = CoverageRule(quality);
  for (const image_t id : model.RegisteredImageIds()) {
    update.cameras.push_back(MakeViewCamera(model.image(id)));
  }
  update.intrinsics = AllIntrinsics(model);
  for (const auto& [id, point] : model.points3D()) AppendPoint(model, id, quality, &update);
  update.num_images = int(model.NumRegisteredImages());
  update.num_points = int(model.NumPoints3D());
  return update;
}

void ViewModel::SetPoint(const ViewUpdate& update, std::size_t i) {
  const float* xyz = &update.xyz[3 * i];
  const std::uint8_t* rgb = &update.rgb[3 * i];
  ViewPointQuality& quality = snapshot_.quality;
  // Measures are kept once any update carried them; a point sent without
  // them (none in a run that measures) counts as seen by none.
  const bool measured = !update.quality.empty();
  if (measured && quality.empty() && !snapshot_.point_ids.empty()) {
    quality.views.assign(snapshot_.point_ids.size(), 0);
    quality.max_angle_deg.assign(snapshot_.point_ids.size(), 0.0f);
    quality.sigma.assign(snapshot_.point_ids.size(), std::numeric_limits<float>::quiet_NaN());
  }
  const bool keep = measured || !quality.empty();
  const std::uint16_t views = measured ? update.quality.views[i] : 0;
  const float angle = measured ? update.quality.max_angle_deg[i] : 0.0f;
  const float sigma = measured ? update.quality.sigma[i] : std::numeric_limits<float>::quiet_NaN();
  const auto [it, added] = slot_.emplace(update.point_ids[i], snapshot_.point_ids.size());
  if (added) {
    snapshot_.point_ids.push_back(update.point_ids[i]);
    snapshot_.xyz.insert(snapshot_.xyz.end(), xyz, xyz + 3);
    snapshot_.rgb.insert(snapshot_.rgb.end(), rgb, rgb + 3);
    if (keep) {
      quality.views.push_back(views);
      quality.max_angle_deg.push_back(angle);
      quality.sigma.push_back(sigma);
    }
    return;
  }
  const std::size_t slot = it->second;
  std::copy(xyz, xyz + 3, snapshot_.xyz.begin() + 3 * slot);
  std::copy(rgb, rgb + 3, snapshot_.rgb.begin() + 3 * slot);
  if (keep) {
    quality.views[slot] = views;
    quality.max_angle_deg[slot] = angle;
    quality.sigma[slot] = sigma;
  }
}

void ViewModel::RemovePoint(point3D_t id) {
  const auto it = slot_.find(id);
  if (it == slot_.end()) return;
  const std::size_t slot = it->second;
  const std::size_t last = snapshot_.point_ids.size() - 1;
  ViewPointQuality& quality = snapshot_.quality;
  if (slot != last) {
    const point3D_t moved = snapshot_.point_ids[last];
    snapshot_.point_ids[slot] = moved;
    std::copy_n(snapshot_.xyz.begin() + 3 * last, 3, snapshot_.xyz.begin() + 3 * slot);
    std::copy_n(snapshot_.rgb.begin() + 3 * last, 3, snapshot_.rgb.begin() + 3 * slot);
    if (!quality.empty()) {
      quality.views[slot] = quality.views[last];
      quality.max_angle_deg[slot] = quality.max_angle_deg[last];
      quality.sigma[slot] = quality.sigma[last];
    }
    slot_[moved] = slot;
  }
  snapshot_.point_ids.pop_back();
  snapshot_.xyz.resize(3 * last);
  snapshot_.rgb.resize(3 * last);
  if (!quality.empty()) {
    quality.views.resize(last);
    quality.max_angle_deg.resize(last);
    quality.sigma.resize(last);
  }
  slot_.erase(it);
}

bool ViewModel::Apply(const ViewUpdate& update) {
  for (const point3D_t id : update.removed_points) RemovePoint(id);
  for (std::size_t i = 0; i < update.point_ids.size(); ++i) SetPoint(update, i);
  if (update.coverage_rule) snapshot_.coverage_rule = update.coverage_rule;
  if (update.surface) snapshot_.surface = update.surface;
  for (const image_t id : update.removed_cameras) snapshot_.cameras.erase(id);
  for (const ViewCamera& camera : update.cameras) snapshot_.cameras[camera.image_id] = camera;
  for (const ViewIntrinsics& k : update.intrinsics) snapshot_.intrinsics[k.camera_id] = k;
  bool lists_changed = false;
  for (const ViewLine& line : update.lines) {
    // An image waits until it registers or is rejected; a rejected image
    // that is given again (--retry-quarantined) may register after all.
    if (line.status == ImageStatusName(ImageStatus::kPending)) {
      snapshot_.pending[line.name] = line.reason;
      lists_changed = true;
    } else {
      lists_changed |= snapshot_.pending.erase(line.name) > 0;
      if (line.status == ImageStatusName(ImageStatus::kRejected)) {
        snapshot_.rejected[line.name] = line.reason;
        lists_changed = true;
      } else {
        lists_changed |= snapshot_.rejected.erase(line.name) > 0;
      }
    }
    snapshot_.latest = line;
  }
  snapshot_.num_images = update.num_images;
  snapshot_.num_points = update.num_points;
  return lists_changed;
}

std::string ModelMessage(const ViewSnapshot& snapshot) {
  std::string out;
  out.reserve(64 + 40 * snapshot.point_ids.size() + 200 * snapshot.cameras.size());
  out += "{\"type\":\"model\",";
  std::vector<const ViewCamera*> cameras;
  cameras.reserve(snapshot.cameras.size());
  for (const auto& [id, camera] : snapshot.cameras) cameras.push_back(&camera);
  AppendCameras(cameras, &out);
  out += ',';
  std::vector<ViewIntrinsics> intrinsics;
  for (const auto& [id, k] : snapshot.intrinsics) intrinsics.push_back(k);
  AppendIntrinsics(intrinsics, &out);
  out += ',';
  AppendPoints(snapshot.point_ids, snapshot.xyz, snapshot.rgb, snapshot.quality, &out);
  AppendCoverageRule(snapshot.coverage_rule, &out);
  AppendSurface(snapshot.surface, &out);
  out += ',';
  AppendNamedReasons("pending", snapshot.pending, &out);
  out += ',';
  AppendNamedReasons("rejected", snapshot.rejected, &out);
  out += ',';
  AppendCounts(snapshot.num_images, snapshot.num_points, &out);
  out += ",\"line\":";
  if (snapshot.latest) {
    AppendLine(*snapshot.latest, &out);
  } else {
    out += "null";
  }
  out += ",\"finished\":";
  out += snapshot.finished ? "true" : "false";
  out += '}';
  return out;
}

std::string UpdateMessage(const ViewUpdate& update, const ViewSnapshot* lists) {
  std::string out;
  out.reserve(256 + 40 * update.point_ids.size() + 200 * update.cameras.size());
  out += "{\"type\":\"update\",\"lines\":[";
  for (std::size_t i = 0; i < update.lines.size(); ++i) {
    if (i > 0) out += ',';
    AppendLine(update.lines[i], &out);
  }
  out += "],";
  std::vector<const ViewCamera*> cameras;
  for (const ViewCamera& camera : update.cameras) cameras.push_back(&camera);
  AppendCameras(cameras, &out);
  out += ',';
  AppendIntegers("removed_cameras", update.removed_cameras, &out);
  out += ',';
  AppendIntrinsics(update.intrinsics, &out);
  out += ',';
  AppendPoints(update.point_ids, update.xyz, update.rgb, update.quality, &out);
  AppendCoverageRule(update.coverage_rule, &out);
  AppendSurface(update.surface, &out);
  out += ',';
  AppendIntegers("removed_points", update.removed_points, &out);
  if (lists) {
    out += ',';
    AppendNamedReasons("pending", lists->pending, &out);
    out += ',';
    AppendNamedReasons("rejected", lists->rejected, &out);
  }
  out += ',';
  AppendCounts(update.num_images, update.num_points, &out);
  out += '}';
  return out;
}

std::string EndMessage() { return "{\"type\":\"end\"}"; }

std::string StatusMessage(const std::string& text) {
  std::string out = "{\"type\":\"status\",\"text\":";
  AppendString(text, &out);
  out += '}';
  return out;
}

}  // namespace flysfm
