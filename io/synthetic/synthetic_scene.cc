#include "io/synthetic/synthetic_scene.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include <opencv2/imgproc.hpp>

#include "io/synthetic/procedural_texture.h"

namespace flysfm {

TexturedFacet::Plane TexturedFacet::ComputePlane() const {
  Plane plane;
  plane.normal = axis_u.cross(axis_v);
  plane.uu = axis_u.squaredNorm();
  plane.uv = axis_u.dot(axis_v);
  plane.vv = axis_v.squaredNorm();
  plane.determinant = plane.uu * plane.vv - plane.uv * plane.uv;
  return plane;
}

Eigen::Vector2d TexturedFacet::Coordinates(const Eigen::Vector3d& point,
                                           const Plane& plane) const {
  // The 2x2 Gram system of the (not necessarily orthogonal) axes.
  const Eigen::Vector3d offset = point - origin;
  const double du = offset.dot(axis_u);
  const double dv = offset.dot(axis_v);
  return Eigen::Vector2d((plane.vv * du - plane.uv * dv) / plane.determinant,
                         (plane.uu * dv - plane.uv * du) / plane.determinant);
}

double TexturedFacet::Intersect(const Eigen::Vector3d& ray_origin,
                                const Eigen::Vector3d& direction, const Plane& plane) const {
  const double along = plane.normal.dot(direction);
  if (std::abs(along) < 1e-12) return -1.0;
  const double lambda = plane.normal.dot(origin - ray_origin) / along;
  if (lambda <= 0.0) return -1.0;
  const Eigen::Vector2d st = Coordinates(ray_origin + lambda * direction, plane);
  const double s = st.x();
  const double t = st.y();
  if (s < 0.0 || s > 1.0 || t < 0.0 || t > 1.0) return -1.0;
  return lambda;
}

float TexturedFacet::Sample(const Eigen::Vector3d& point_on_facet, const Plane& plane) const {
  const Eigen::Vector2d st = Coordinates(point_on_facet, plane);
  const double s = st.x();
  const double t = st.y();
  // Texel coordinates, clamped so that bilinear reads stay inside.
  const double x =
      std::clamp(s * texture.cols - 0.5, 0.0, texture.cols - 1.001);
  const double y =
      std::clamp(t * texture.rows - 0.5, 0.0, texture.rows - 1.001);
  const int x0 = static_cast<int>(x);
  const int y0 = static_cast<int>(y);
  const float fx = static_cast<float>(x - x0);
  const float fy = static_cast<float>(y - y0);
  const float* top = texture.ptr<float>(y0) + x0;
  const float* bottom = texture.ptr<float>(y0 + 1) + x0;
  return (1 - fy) * ((1 - fx) * top[0] + fx * top[1]) +
         fy * ((1 - fx) * bottom[0] + fx * bottom[1]);
}

TexturedScene MakeFacetScene(std::uint32_t seed) {
  // Texels of 8 mm: about half a pixel at the wall for a 500 px focal length.
  constexpr double kTexelsPerMetre = 125.0;
  TexturedScene scene;
  std::uint32_t texture_seed = seed * 101u;
  const auto add = [&](const Eigen::Vector3d& origin, const Eigen::Vector3d& u,
                       const Eigen::Vector3d& v) {
    TexturedFacet facet;
    facet.origin = origin;
    facet.axis_u = u;
    facet.axis_v = v;
    const int cols = static_cast<int>(std::ceil(u.norm() * kTexelsPerMetre));
    const int rows = static_cast<int>(std::ceil(v.norm() * kTexelsPerMetre));
    cv::Mat texture;
    MakeTexture(cols, rows, ++texture_seed).convertTo(texture, CV_32F);
    cv::GaussianBlur(texture, facet.texture, cv::Size(), 2.0);
    scene.facets.push_back(facet);
  };
  const Eigen::Vector3d x = Eigen::Vector3d::UnitX();
  const Eigen::Vector3d y = Eigen::Vector3d::UnitY();
  const Eigen::Vector3d z = Eigen::Vector3d::UnitZ();
  add({-4.0, -3.0, 2.0}, 8.0 * x, 6.0 * y);  // back wall
  add({-1.8, -1.2, 0.5}, 1.2 * x, 1.0 * y);
  add({0.4, -1.5, 1.0}, 1.4 * x, 1.2 * y);
  add({-0.7, 0.3, -0.5}, 1.0 * x, 0.9 * y);
  // Two slanted facets: the affine map between views is not a similarity.
  add({0.9, 0.2, -1.0}, 1.0 * x + 0.5 * z, 1.0 * y);
  add({-2.2, 0.6, 0.0}, 1.1 * x - 0.4 * z, 0.9 * y + 0.3 * z);
  add({-0.3, -1.9, -1.5}, 0.8 * x, 0.7 * y);
  return scene;
}

RenderedView Render(const TexturedScene& scene, const Camera& camera,
                    const Rigid3d& cam_from_world, int supersampling) {
  const Eigen::Matrix3d world_from_cam =
      cam_from_world.rotation.conjugate().toRotationMatrix();
  const Eigen::Vector3d center = ProjectionCenter(cam_from_world);
  std::vector<TexturedFacet::Plane> planes;
  for (const TexturedFacet& facet : scene.facets) planes.push_back(facet.ComputePlane());
  cv::Mat sum(camera.height, camera.width, CV_32F, cv::Scalar(0));
  RenderedView view;
  view.depth = cv::Mat(camera.height, camera.width, CV_32F,
                       cv::Scalar(std::numeric_limits<float>::infinity()));
  for (int row = 0; row < camera.height; ++row) {
    for (int col = 0; col < camera.width; ++col) {
      float total = 0.f;
      for (int i = 0; i < supersampling; ++i) {
        for (int j = 0; j < supersampling; ++j) {
          const Eigen::Vector2d pixel(col - 0.5 + (j + 0.5) / supersampling,
                                      row - 0.5 + (i + 0.5) / supersampling);
          const Eigen::Vector3d ray_in_cam =
              camera.CamFromImg(pixel).homogeneous();
          const Eigen::Vector3d direction = world_from_cam * ray_in_cam;
          double nearest = std::numeric_limits<double>::infinity();
          int hit = -1;
          for (int f = 0; f < int(scene.facets.size()); ++f) {
            const double lambda = scene.facets[f].Intersect(center, direction, planes[f]);
            if (lambda > 0.0 && lambda < nearest) {
              nearest = lambda;
              hit = f;
            }
          }
          if (hit < 0) continue;
          total += scene.facets[hit].Sample(center + nearest * direction, planes[hit]);
          // The ray's z in the camera is 1, so lambda is the depth.
          if (i == supersampling / 2 && j == supersampling / 2) {
            view.depth.at<float>(row, col) = static_cast<float>(nearest);
          }
        }
      }
      sum.at<float>(row, col) = total / (supersampling * supersampling);
    }
  }
  sum.convertTo(view.image, CV_8U);
  return view;
}

bool IsVisible(const TexturedScene& scene, const Camera& camera,
               const Rigid3d& cam_from_world, const Eigen::Vector3d& point,
               double relative_tolerance) {
  const Eigen::Vector3d in_cam = cam_from_world * point;
  if (in_cam.z() <= 0.0) return false;
  const Eigen::Vector2d pixel = camera.ImgFromCam(in_cam);
  if (pixel.x() < -0.5 || pixel.y() < -0.5 || pixel.x() > camera.width - 0.5 ||
      pixel.y() > camera.height - 0.5) {
    return false;
  }
  const Eigen::Vector3d center = ProjectionCenter(cam_from_world);
  const Eigen::Vector3d direction = point - center;  // lambda = 1 at the point
  for (const TexturedFacet& facet : scene.facets) {
    const double lambda = facet.Intersect(center, direction);
    if (lambda > 0.0 && lambda < 1.0 - relative_tolerance) return false;
  }
  return true;
}

std::vector<Eigen::Vector3d> SamplePointsOnFacets(const TexturedScene& scene,
                                                  int count,
                                                  std::mt19937& rng) {
  std::vector<double> areas;
  for (const TexturedFacet& facet : scene.facets) {
    areas.push_back(facet.axis_u.cross(facet.axis_v).norm());
  }
  std::discrete_distribution<int> which(areas.begin(), areas.end());
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  std::vector<Eigen::Vector3d> points;
  for (int i = 0; i < count; ++i) {
    points.push_back(scene.facets[which(rng)].At(unit(rng), unit(rng)));
  }
  return points;
}

}  // namespace flysfm
