#include "geometry/normalization.h"

#include <cmath>

namespace flysfm {
namespace {

template <typename Get>
bool NormalizeImpl(int n, Get get, std::vector<Eigen::Vector2d>* normalized,
                   Eigen::Matrix3d* transform) {
  if (n <= 0) return false;
  Eigen::Vector2d centroid = Eigen::Vector2d::Zero();
  for (int i = 0; i < n; ++i) {
    if (!get(i).allFinite()) return false;
    centroid += get(i);
  }
  centroid /= n;
  double mean_distance = 0;
  for (int i = 0; i < n; ++i) mean_distance += (get(i) - centroid).norm();
  mean_distance /= n;
  if (!(mean_distance > 1e-12 * (1.0 + centroid.norm()))) return false;
  const double scale = std::sqrt(2.0) / mean_distance;
  *transform << scale, 0, -scale * centroid.x(),  //
      0, scale, -scale * centroid.y(),            //
      0, 0, 1;
  normalized->resize(n);
  for (int i = 0; i < n; ++i) (*normalized)[i] = scale * (get(i) - centroid);
  return true;
}

}  // namespace

bool NormalizePoints(const std::vector<Eigen::Vector2d>& points,
                     std::vector<Eigen::Vector2d>* normalized,
                     Eigen::Matrix3d* transform) {
  return NormalizeImpl(
      static_cast<int>(points.size()),
      [&](int i) -> const Eigen::Vector2d& { return points[i]; }, normalized,
      transform);
}

bool AllFinite(const std::vector<Eigen::Vector2d>& points) {
  for (const auto& p : points) {
    if (!p.allFinite()) return false;
  }
  return true;
}

bool AllFinite(const std::vector<Eigen::Vector3d>& points) {
  for (const auto& p : points) {
    if (!p.allFinite()) return false;
  }
  return true;
}

}  // namespace flysfm
