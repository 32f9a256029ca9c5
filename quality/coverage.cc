#include "quality/coverage.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>
#include <map>
#include <stdexcept>
#include <utility>

#include <Eigen/Eigenvalues>

#include <CGAL/Delaunay_triangulation_3.h>
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Triangulation_cell_base_with_info_3.h>
#include <CGAL/Triangulation_vertex_base_with_info_3.h>

#include "geometry/statistics.h"

namespace flysfm {
namespace {

using Kernel = CGAL::Exact_predicates_inexact_constructions_kernel;
// A vertex knows its point (an index into the points used); a cell counts the
// rays that crossed it.
using VertexBase = CGAL::Triangulation_vertex_base_with_info_3<std::size_t, Kernel>;
using CellBase = CGAL::Triangulation_cell_base_with_info_3<int, Kernel>;
using Tds = CGAL::Triangulation_data_structure_3<VertexBase, CellBase>;
using Delaunay = CGAL::Delaunay_triangulation_3<Kernel, Tds>;
using CgalPoint = Kernel::Point_3;

constexpr double kPi = 3.14159265358979323846;

Eigen::Vector3d ToEigen(const CgalPoint& p) { return {p.x(), p.y(), p.z()}; }
CgalPoint ToCgal(const Eigen::Vector3d& p) { return {p.x(), p.y(), p.z()}; }

double AngleDeg(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return std::atan2(a.cross(b).norm(), a.dot(b)) * 180.0 / kPi;
}

// A registered image as the surface needs it.
struct View {
  image_t image_id = kInvalidImageId;
  Eigen::Vector3d center = Eigen::Vector3d::Zero();
  double focal = 0;
  // Where it looked: the mean of the points used that it observes.
  Eigen::Vector3d looked_at = Eigen::Vector3d::Zero();
  int num_looked_at = 0;
};

// One point the surface is built from, with the views that observe it.
struct UsedPoint {
  Eigen::Vector3d xyz = Eigen::Vector3d::Zero();
  std::vector<std::size_t> views;  // indices into the views, ascending
};

// The largest angle between two of `rays` (unit vectors): every pair of at
// most `limit` rays taken evenly (a face's views are few).
double MaxPairAngleDeg(const std::vector<Eigen::Vector3d>& rays, std::size_t limit = 16) {
  const std::size_t step = std::max<std::size_t>(1, (rays.size() + limit - 1) / limit);
  double best = 0;
  for (std::size_t i = 0; i < rays.size(); i += step) {
    for (std::size_t j = i + step; j < rays.size(); j += step) {
      best = std::max(best, AngleDeg(rays[i], rays[j]));
    }
  }
  return best;
}

// The views that see at least one of the corners. One is enough: on a
// noisy surface the hull's triangles span several points' spacing, and the
// images that saw the points inside them saw the triangle; the facing test
// (Update) keeps out the images that saw a corner from another side.
std::vector<std::size_t> ViewsOfCorners(const std::array<const UsedPoint*, 3>& corners) {
  std::vector<std::size_t> views;
  for (const UsedPoint* corner : corners) {
    views.insert(views.end(), corner->views.begin(), corner->views.end());
  }
  std::sort(views.begin(), views.end());
  views.erase(std::unique(views.begin(), views.end()), views.end());
  return views;
}

// Up, from cameras held upright: their images' x axes are level, so up is
// the direction least along any of them (the smallest eigenvector of their
// scatter), turned against their y axes (down). Pitched cameras do not tilt
// it, as a mean of y axes would be tilted by shots that all look down at an
// object from one side. Shots that all share one x axis (one facade, shot
// square on) leave it free about that axis: then the mean y axis decides.
Eigen::Vector3d UpFromCameras(const Eigen::Matrix3d& right_scatter,
                              const Eigen::Vector3d& down_sum) {
  const Eigen::Vector3d fallback =
      down_sum.norm() > 1e-9 ? Eigen::Vector3d(-down_sum.normalized()) : Eigen::Vector3d(0, -1, 0);
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> solver(right_scatter);
  const Eigen::Vector3d values = solver.eigenvalues();  // ascending
  if (values(2) <= 0 || values(1) < 0.05 * values(2)) return fallback;
  Eigen::Vector3d up = solver.eigenvectors().col(0);
  if (up.dot(fallback) < 0) up = -up;
  return up.normalized();
}

// How far round the object a step goes: the photographer's own spacing (the
// median, over the shots, of the angle round the vertical axis through the
// object's centre to the nearest other shot), at most `max_step`. Each new
// area must be seen twice before a later step can match it: a step as wide
// as the walk's own spacing keeps that, as the walk did.
double StepRound(const std::vector<View>& views, const Eigen::Vector3d& pivot,
                 const Eigen::Vector3d& up, double max_step) {
  const Eigen::Vector3d a = up.unitOrthogonal();
  const Eigen::Vector3d b = up.cross(a);
  std::vector<double> azimuths;
  for (const View& view : views) {
    const Eigen::Vector3d offset = view.center - pivot;
    if ((offset - offset.dot(up) * up).norm() <= 0) continue;
    azimuths.push_back(std::atan2(offset.dot(b), offset.dot(a)));
  }
  if (azimuths.size() < 2) return max_step;
  std::sort(azimuths.begin(), azimuths.end());
  const std::size_t n = azimuths.size();
  std::vector<double> nearest(n);
  for (std::size_t i = 0; i < n; ++i) {
    const double before = i > 0 ? azimuths[i] - azimuths[i - 1] : azimuths[0] + 2 * kPi - azimuths[n - 1];
    const double after = i + 1 < n ? azimuths[i + 1] - azimuths[i] : azimuths[0] + 2 * kPi - azimuths[n - 1];
    nearest[i] = std::min(before, after);
  }
  // Shots from one place (nearly 0 apart) step at least a degree.
  return std::clamp(Median(nearest), kPi / 180.0, max_step);
}

// Camera looking along `direction` from `position`, its image's y axis (down)
// against `up`.
Rigid3d LookAt(const Eigen::Vector3d& position, const Eigen::Vector3d& direction,
               const Eigen::Vector3d& up) {
  const Eigen::Vector3d z = direction.normalized();
  Eigen::Vector3d y = -up - (-up).dot(z) * z;
  if (y.norm() < 1e-9) y = z.unitOrthogonal();
  y.normalize();
  const Eigen::Vector3d x = y.cross(z);
  Eigen::Matrix3d rotation;
  rotation.row(0) = x.transpose();
  rotation.row(1) = y.transpose();
  rotation.row(2) = z.transpose();
  return Rigid3d(rotation, -rotation * position);
}

}  // namespace

void Coverage::Options::Check() const {
  const auto require = [](bool ok, const char* what) {
    if (!ok) throw std::invalid_argument(std::string("Coverage::Options: ") + what);
  };
  require(min_views >= 2, "min_views must be at least 2");
  require(min_angle_deg >= 0 && min_angle_deg < 180, "min_angle_deg must be in [0, 180)");
  require(max_incidence_deg > 0 && max_incidence_deg <= 90,
          "max_incidence_deg must be in (0, 90]");
  require(max_points >= 4, "max_points must be at least 4");
  require(max_rays_per_point >= 1, "max_rays_per_point must be at least 1");
  require(max_suggestions >= 0, "max_suggestions must not be negative");
  require(min_suggestion_share >= 0 && min_suggestion_share <= 1,
          "min_suggestion_share must be in [0, 1]");
  require(max_step_deg > 0 && max_step_deg <= 180, "max_step_deg must be in (0, 180]");
}

const char* FaceClassName(Coverage::FaceClass face_class) {
  switch (face_class) {
    case Coverage::FaceClass::kWellCovered: return "well_covered";
    case Coverage::FaceClass::kNarrowAngle: return "narrow_angle";
    case Coverage::FaceClass::kFewViews: return "few_views";
    case Coverage::FaceClass::kUnderside: return "underside";
    case Coverage::FaceClass::kOutOfReach: return "out_of_reach";
  }
  return "unknown";
}

std::array<std::uint8_t, 3> FaceClassColour(Coverage::FaceClass face_class) {
  switch (face_class) {
    case Coverage::FaceClass::kWellCovered: return {40, 200, 70};
    case Coverage::FaceClass::kNarrowAngle: return {255, 150, 20};
    case Coverage::FaceClass::kFewViews: return {230, 40, 40};
    case Coverage::FaceClass::kUnderside: return {128, 128, 128};
    case Coverage::FaceClass::kOutOfReach: return {110, 140, 190};
  }
  return {0, 0, 0};
}

Coverage::Coverage() : Coverage(Options()) {}

Coverage::Coverage(Options options) : options_(std::move(options)) { options_.Check(); }

void Coverage::Update(const Reconstruction& reconstruction) {
  const auto start = std::chrono::steady_clock::now();
  faces_.clear();
  suggestions_.clear();
  summary_ = Summary();

  // The views, and the up direction they agree on.
  std::vector<View> views;
  std::map<image_t, std::size_t> view_of;
  Eigen::Vector3d image_down_sum = Eigen::Vector3d::Zero();
  Eigen::Matrix3d image_right_scatter = Eigen::Matrix3d::Zero();
  // The largest sub-model alone: the others' frames are their own until
  // they merge with it.
  const auto models = reconstruction.Models();
  const model_t model_id = models.empty() ? kInvalidModelId : models.front().first;
  for (const image_t id : reconstruction.RegisteredImageIds()) {
    const Image& image = reconstruction.image(id);
    if (image.model_id != model_id) continue;
    const Rigid3d& cam_from_world = *image.cam_from_world;
    View view;
    view.image_id = id;
    view.center = ProjectionCenter(cam_from_world);
    view.focal = reconstruction.camera(image.camera_id).MeanFocalLength();
    view_of[id] = views.size();
    views.push_back(view);
    const Eigen::Matrix3d rotation = cam_from_world.rotation.toRotationMatrix();
    image_down_sum += rotation.row(1).transpose();
    image_right_scatter += rotation.row(0).transpose() * rotation.row(0);
  }
  up_ = UpFromCameras(image_right_scatter, image_down_sum);

  // The points, evenly taken.
  std::vector<point3D_t> ids;
  ids.reserve(reconstruction.NumPoints3D());
  for (const auto& [id, point] : reconstruction.points3D()) ids.push_back(id);
  std::sort(ids.begin(), ids.end());
  const std::size_t step =
      std::max<std::size_t>(1, (ids.size() + std::size_t(options_.max_points) - 1) /
                                   std::size_t(options_.max_points));
  std::vector<UsedPoint> points;
  std::vector<std::pair<CgalPoint, std::size_t>> cgal_points;
  for (std::size_t i = 0; i < ids.size(); i += step) {
    const Point3D& point = reconstruction.point3D(ids[i]);
    UsedPoint used;
    used.xyz = point.xyz;
    for (const TrackElement& element : point.track) {
      const auto it = view_of.find(element.image_id);
      if (it != view_of.end()) used.views.push_back(it->second);
    }
    std::sort(used.views.begin(), used.views.end());
    used.views.erase(std::unique(used.views.begin(), used.views.end()), used.views.end());
    if (used.views.empty()) continue;
    for (const std::size_t v : used.views) {
      views[v].looked_at += used.xyz;
      ++views[v].num_looked_at;
    }
    cgal_points.emplace_back(ToCgal(used.xyz), points.size());
    points.push_back(std::move(used));
  }
  summary_.points_used = points.size();
  if (points.size() < 4 || views.size() < 2) {
    summary_.ms = std::chrono::duration<double, std::milli>(
                      std::chrono::steady_clock::now() - start).count();
    return;
  }

  Delaunay triangulation(cgal_points.begin(), cgal_points.end());
  if (triangulation.dimension() < 3) {
    summary_.ms = std::chrono::duration<double, std::milli>(
                      std::chrono::steady_clock::now() - start).count();
    return;  // the points lie on a plane or a line: no volume to carve
  }
  for (auto cell = triangulation.all_cells_begin(); cell != triangulation.all_cells_end(); ++cell) {
    cell->info() = 0;
  }

  // Carving: each ray from a camera to a point it sees crosses empty space,
  // but for its last stretch: a noisy surface is rough at the scale of its
  // points' noise, and a ray carving right up to its point cuts the thin
  // cells between the point and its neighbours, inside the surface as often
  // as not. The stretch left is half the points' typical spacing (the median
  // of each point's shortest Delaunay edge), which a surface's noise must be
  // smaller than for the surface to be seen at all.
  std::vector<double> shortest(points.size(), std::numeric_limits<double>::infinity());
  for (auto edge = triangulation.finite_edges_begin(); edge != triangulation.finite_edges_end();
       ++edge) {
    const auto a = edge->first->vertex(edge->second);
    const auto b = edge->first->vertex(edge->third);
    const double length = std::sqrt(CGAL::squared_distance(a->point(), b->point()));
    shortest[a->info()] = std::min(shortest[a->info()], length);
    shortest[b->info()] = std::min(shortest[b->info()], length);
  }
  const double stretch = 0.5 * Median(std::vector<double>(shortest.begin(), shortest.end()));
  std::vector<double> distances;
  for (auto vertex = triangulation.finite_vertices_begin();
       vertex != triangulation.finite_vertices_end(); ++vertex) {
    const UsedPoint& point = points[vertex->info()];
    const std::size_t ray_step = std::max<std::size_t>(
        1, (point.views.size() + std::size_t(options_.max_rays_per_point) - 1) /
               std::size_t(options_.max_rays_per_point));
    for (std::size_t k = 0; k < point.views.size(); k += ray_step) {
      const Eigen::Vector3d& center = views[point.views[k]].center;
      distances.push_back((center - point.xyz).norm());
      const double length = (center - point.xyz).norm();
      if (length <= stretch) continue;
      const Eigen::Vector3d from = point.xyz + (stretch / length) * (center - point.xyz);
      ++summary_.rays;
      try {
        // A ray that starts outside the hull never enters it (the hull is
        // convex), and CGAL's walk must not start outside along a ray that
        // leaves it.
        const Delaunay::Cell_handle first = triangulation.locate(ToCgal(from), vertex->cell());
        if (triangulation.is_infinite(first)) continue;
        auto cell = triangulation.segment_traverser_cells_begin(ToCgal(from), ToCgal(center),
                                                                first);
        const auto end = triangulation.segment_traverser_cells_end();
        // A ray leaves the hull once (it is convex); the bound only guards
        // against a degenerate walk.
        for (std::size_t steps = 0; cell != end && steps < 100000; ++cell, ++steps) {
          const Delaunay::Cell_handle handle = cell;
          if (triangulation.is_infinite(handle)) break;
          handle->info() += 1;
        }
      } catch (const std::exception&) {
        // A walk CGAL refuses (a degenerate configuration) carves nothing.
      }
    }
  }

  // The photographer's own distance and heights bound where a shot can go.
  const double distance = distances.empty() ? 1.0 : Median(distances);
  double low = std::numeric_limits<double>::infinity();
  double high = -std::numeric_limits<double>::infinity();
  for (const View& view : views) {
    low = std::min(low, up_.dot(view.center));
    high = std::max(high, up_.dot(view.center));
  }
  const double cos_incidence = std::cos(options_.max_incidence_deg * kPi / 180.0);
  // Where a photographer would stand for a face: out along its normal at
  // their distance, at a height they have used.
  const auto standpoint = [&](const Eigen::Vector3d& at, const Eigen::Vector3d& normal) {
    Eigen::Vector3d position = at + distance * normal;
    const double height = up_.dot(position);
    position += up_ * (std::clamp(height, low, high) - height);
    return position;
  };
  // Seen from there less obliquely than the views that count.
  const auto reachable = [&](const Eigen::Vector3d& at, const Eigen::Vector3d& normal) {
    const Eigen::Vector3d to = standpoint(at, normal) - at;
    return to.norm() > 0 && normal.dot(to) >= cos_incidence * to.norm();
  };

  // The surface: facets between a cell no ray crossed and empty space
  // (a crossed cell or the outside), facing the empty side.
  std::vector<std::pair<double, double>> gsd_by_area;
  for (auto cell = triangulation.finite_cells_begin(); cell != triangulation.finite_cells_end();
       ++cell) {
    if (cell->info() > 0) continue;
    for (int i = 0; i < 4; ++i) {
      const Delaunay::Cell_handle neighbour = cell->neighbor(i);
      if (!triangulation.is_infinite(neighbour) && neighbour->info() == 0) continue;
      Face face;
      std::array<const UsedPoint*, 3> corners{};
      for (int k = 0; k < 3; ++k) {
        const auto vertex = cell->vertex((i + 1 + k) % 4);
        corners[std::size_t(k)] = &points[vertex->info()];
        face.corners[std::size_t(k)] = ToEigen(vertex->point());
      }
      const Eigen::Vector3d cross =
          (face.corners[1] - face.corners[0]).cross(face.corners[2] - face.corners[0]);
      face.area = 0.5 * cross.norm();
      if (face.area <= 0) continue;
      face.normal = cross.normalized();
      // Out of the object: away from the cell's fourth vertex.
      if (face.normal.dot(ToEigen(cell->vertex(i)->point()) - face.corners[0]) > 0) {
        face.normal = -face.normal;
      }
      const Eigen::Vector3d centroid = (face.corners[0] + face.corners[1] + face.corners[2]) / 3;
      std::vector<Eigen::Vector3d> rays;
      std::vector<double> gsds;
      for (const std::size_t v : ViewsOfCorners(corners)) {
        const Eigen::Vector3d to_camera = views[v].center - centroid;
        const double distance = to_camera.norm();
        if (distance <= 0 || face.normal.dot(to_camera) < cos_incidence * distance) continue;
        rays.push_back(to_camera / distance);
        if (views[v].focal > 0) gsds.push_back(distance / views[v].focal);
      }
      face.views = int(rays.size());
      face.max_angle_deg = MaxPairAngleDeg(rays);
      face.gsd = gsds.empty() ? 0 : Median(gsds);
      if (face.normal.dot(up_) < -0.5) {
        face.face_class = FaceClass::kUnderside;
      } else if (!reachable(centroid, face.normal)) {
        face.face_class = FaceClass::kOutOfReach;
      } else if (face.views < options_.min_views) {
        face.face_class = FaceClass::kFewViews;
      } else if (face.max_angle_deg < options_.min_angle_deg) {
        face.face_class = FaceClass::kNarrowAngle;
      } else {
        face.face_class = FaceClass::kWellCovered;
      }
      switch (face.face_class) {
        case FaceClass::kUnderside: summary_.underside_area += face.area; break;
        case FaceClass::kOutOfReach: summary_.out_of_reach_area += face.area; break;
        case FaceClass::kFewViews: summary_.few_views_area += face.area; break;
        case FaceClass::kNarrowAngle: summary_.narrow_angle_area += face.area; break;
        case FaceClass::kWellCovered: summary_.well_covered_area += face.area; break;
      }
      if (face.face_class != FaceClass::kUnderside &&
          face.face_class != FaceClass::kOutOfReach && face.gsd > 0) {
        gsd_by_area.emplace_back(face.gsd, face.area);
      }
      faces_.push_back(face);
    }
  }
  summary_.faces = faces_.size();
  summary_.area = summary_.well_covered_area + summary_.narrow_angle_area + summary_.few_views_area;
  summary_.well_covered_share =
      summary_.area > 0 ? summary_.well_covered_area / summary_.area : 0;
  if (!gsd_by_area.empty()) {
    std::sort(gsd_by_area.begin(), gsd_by_area.end());
    double total = 0;
    for (const auto& [gsd, area] : gsd_by_area) total += area;
    double below = 0;
    for (const auto& [gsd, area] : gsd_by_area) {
      below += area;
      if (below >= 0.5 * total) {
        summary_.median_gsd = gsd;
        break;
      }
    }
  }

  // The object's centre, which a photographer walks round.
  Eigen::Vector3d pivot = Eigen::Vector3d::Zero();
  for (const UsedPoint& point : points) pivot += point.xyz;
  pivot /= double(points.size());
  // The nearest the photographer stood to it, on the level.
  double nearest_distance = std::numeric_limits<double>::infinity();
  for (const View& view : views) {
    const Eigen::Vector3d offset = view.center - pivot;
    nearest_distance = std::min(nearest_distance, (offset - offset.dot(up_) * up_).norm());
  }
  // Sides of the object, named from the first shot: "front" faces it.
  const Rigid3d& first = *reconstruction.image(views.front().image_id).cam_from_world;
  const Eigen::Matrix3d first_rotation = first.rotation.toRotationMatrix();
  Eigen::Vector3d forward = first_rotation.row(2).transpose();
  forward -= forward.dot(up_) * up_;
  if (forward.norm() < 1e-9) forward = up_.unitOrthogonal();
  forward.normalize();
  // The first image's x axis (right), levelled: x = y x z with y = -up.
  const Eigen::Vector3d right = forward.cross(up_).normalized();

  struct Group {
    double area = 0;
    double few_views_area = 0;
    Eigen::Vector3d centroid = Eigen::Vector3d::Zero();  // area-weighted sum
    Eigen::Vector3d normal = Eigen::Vector3d::Zero();    // area-weighted sum
  };
  // Eight sides around the up axis, and the top.
  std::array<Group, 9> groups{};
  for (const Face& face : faces_) {
    if (face.face_class != FaceClass::kFewViews && face.face_class != FaceClass::kNarrowAngle) {
      continue;
    }
    std::size_t side = 8;
    if (face.normal.dot(up_) <= 0.7) {
      // Azimuth of the normal: 0 towards the first shot, 90 to its right.
      const double azimuth =
          std::atan2(face.normal.dot(right), -face.normal.dot(forward)) * 180.0 / kPi;
      side = std::size_t(std::lround(azimuth / 45.0 + 8)) % 8;
    }
    Group& group = groups[side];
    group.area += face.area;
    if (face.face_class == FaceClass::kFewViews) group.few_views_area += face.area;
    const Eigen::Vector3d centroid = (face.corners[0] + face.corners[1] + face.corners[2]) / 3;
    group.centroid += face.area * centroid;
    group.normal += face.area * face.normal;
  }
  static const char* const kSideNames[9] = {
      "the side the first shot faced", "the front right", "the right side", "the back right",
      "the back", "the back left", "the left side", "the front left", "the top"};
  std::vector<std::pair<double, std::size_t>> order;
  for (std::size_t side = 0; side < groups.size(); ++side) {
    if (groups[side].area > 0) order.emplace_back(groups[side].area, side);
  }
  std::sort(order.rbegin(), order.rend());
  for (const auto& [area, side] : order) {
    if (int(suggestions_.size()) >= options_.max_suggestions) break;
    const double share = summary_.area > 0 ? area / summary_.area : 0;
    if (share < options_.min_suggestion_share) break;
    const Group& group = groups[side];
    const Eigen::Vector3d centroid = group.centroid / group.area;
    if (group.normal.norm() <= 0) continue;
    const Eigen::Vector3d normal = group.normal.normalized();
    if (!reachable(centroid, normal)) continue;
    Suggestion suggestion;
    suggestion.position = standpoint(centroid, normal);
    // A shot further round the object than max_step_deg from every shot
    // matches none of them: then the suggestion is the nearest shot (round
    // the vertical axis through the object's centre) taken again
    // max_step_deg further round towards the side, looking where it looked
    // turned as far: the next step of a walk round the object.
    const auto azimuth = [&](const Eigen::Vector3d& p) {
      const Eigen::Vector3d offset = p - pivot;
      return std::atan2(offset.dot(right), offset.dot(-forward));
    };
    const auto wrap = [](double angle) {
      return std::remainder(angle, 2 * kPi);
    };
    Eigen::Vector3d target = centroid;
    bool stepping = false;
    const double step = StepRound(views, pivot, up_, options_.max_step_deg * kPi / 180.0);
    const Eigen::Vector3d ideal_offset = suggestion.position - pivot;
    if ((ideal_offset - ideal_offset.dot(up_) * up_).norm() > 1e-6 * distance) {
      const double ideal = azimuth(suggestion.position);
      const View* nearest = nullptr;
      double apart = 0;
      for (const View& view : views) {
        const double d = wrap(ideal - azimuth(view.center));
        if (nearest == nullptr || std::abs(d) < std::abs(apart)) {
          nearest = &view;
          apart = d;
        }
      }
      if (nearest != nullptr && std::abs(apart) > step) {
        // right = up x (-forward): a turn by +a about up adds a to the
        // azimuth.
        const Eigen::AngleAxisd rotation(apart > 0 ? step : -step, up_);
        suggestion.position = pivot + rotation * (nearest->center - pivot);
        if (nearest->num_looked_at > 0) {
          target = pivot + rotation * (nearest->looked_at / nearest->num_looked_at - pivot);
        }
        stepping = true;
      }
    }
    // At a distance from the object the photographer has stood at: not
    // inside it (a standpoint for a roof's slope may fall there).
    Eigen::Vector3d offset = suggestion.position - pivot;
    const double along_up = offset.dot(up_);
    Eigen::Vector3d level = offset - along_up * up_;
    if (level.norm() < nearest_distance) {
      if (level.norm() <= 1e-9 * distance) continue;
      level *= nearest_distance / level.norm();
      suggestion.position = pivot + level + along_up * up_;
    }
    const Eigen::Vector3d to_side = target - suggestion.position;
    if (to_side.norm() <= 0) continue;
    suggestion.direction = to_side.normalized();
    suggestion.cam_from_world = LookAt(suggestion.position, suggestion.direction, up_);
    suggestion.area_share = share;
    char reason[240];
    if (group.few_views_area >= 0.5 * group.area) {
      std::snprintf(reason, sizeof(reason), "%.0f %% of the surface, on %s, seen by fewer than %d photos",
                    100 * share, kSideNames[side], options_.min_views);
    } else {
      std::snprintf(reason, sizeof(reason), "%.0f %% of the surface, on %s, seen under less than %.0f degrees",
                    100 * share, kSideNames[side], options_.min_angle_deg);
    }
    suggestion.reason = reason;
    if (stepping) suggestion.reason += " (a step towards it, near enough to the shots to match)";
    suggestion.step = stepping;
    suggestions_.push_back(std::move(suggestion));
  }
  summary_.ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
}

}  // namespace flysfm
