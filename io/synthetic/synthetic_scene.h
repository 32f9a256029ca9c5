#pragma once

// A small renderer of textured planar facets, for tests that need real
// pixels with exact geometry: images of a 3D scene from any pose, with the
// exact depth of every pixel and exact visibility of any 3D point. Pixel
// (col, row) shows the camera's image point (col, row) (OpenCV's pixel-centre
// convention, as LSM and cv::KeyPoint use).

#include <cstdint>
#include <random>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "geometry/camera.h"
#include "geometry/rigid3d.h"

namespace flysfm {

// A textured parallelogram: origin + s axis_u + t axis_v for s, t in [0, 1].
// The texture (CV_32F, grey levels) spans it: texel (c, r) has its centre at
// s = (c + 0.5) / cols, t = (r + 0.5) / rows.
struct TexturedFacet {
  Eigen::Vector3d origin = Eigen::Vector3d::Zero();
  Eigen::Vector3d axis_u = Eigen::Vector3d::UnitX();
  Eigen::Vector3d axis_v = Eigen::Vector3d::UnitY();
  cv::Mat texture;

  // What every ray needs of the axes, computed once for the 1.2 million
  // rays of a view rather than per ray.
  struct Plane {
    Eigen::Vector3d normal;                   // axis_u x axis_v
    double uu = 0, uv = 0, vv = 0;            // the axes' Gram matrix
    double determinant = 0;                   // uu vv - uv^2
  };
  Plane ComputePlane() const;

  // Ray parameter of the hit of origin + lambda direction, or a negative
  // value when the ray misses the facet.
  double Intersect(const Eigen::Vector3d& ray_origin, const Eigen::Vector3d& direction,
                   const Plane& plane) const;
  double Intersect(const Eigen::Vector3d& ray_origin,
                   const Eigen::Vector3d& direction) const {
    return Intersect(ray_origin, direction, ComputePlane());
  }
  float Sample(const Eigen::Vector3d& point_on_facet, const Plane& plane) const;
  // Facet coordinates (s, t) of a point on the facet's plane.
  Eigen::Vector2d Coordinates(const Eigen::Vector3d& point, const Plane& plane) const;
  // A point at facet coordinates (s, t).
  Eigen::Vector3d At(double s, double t) const {
    return origin + s * axis_u + t * axis_v;
  }
};

struct TexturedScene {
  std::vector<TexturedFacet> facets;
};

// A back wall at z = 2 (8 m x 6 m) and six smaller facets (about 1 m, two
// of them slanted) between z = -1.5 and z = 1, overlapping in depth: seen from
// cameras near (x, y, -5) looking along +z they occlude each other and the
// wall. Textures from MakeTexture, blurred by two texels (about a pixel at the
// wall): band-limited, so that what a view shows does not alias.
TexturedScene MakeFacetScene(std::uint32_t seed);

struct RenderedView {
  cv::Mat image;  // CV_8UC1
  cv::Mat depth;  // CV_32FC1, z in the camera; +inf where no facet is hit
};

// Renders by inverse mapping: for each of `supersampling`^2 sub-pixel rays
// per pixel the nearest facet hit, its texture sampled bilinearly; the
// pixel is their mean (the sensor's area integration).
RenderedView Render(const TexturedScene& scene, const Camera& camera,
                    const Rigid3d& cam_from_world, int supersampling = 3);

// True when the point lies in front of the camera, projects inside the
// image, and no facet crosses the segment from the camera centre to it
// (up to `relative_tolerance` of its distance, for points on a facet).
bool IsVisible(const TexturedScene& scene, const Camera& camera,
               const Rigid3d& cam_from_world, const Eigen::Vector3d& point,
               double relative_tolerance = 1e-6);

// `count` points uniform over the facets' total area.
std::vector<Eigen::Vector3d> SamplePointsOnFacets(const TexturedScene& scene,
                                                  int count, std::mt19937& rng);

}  // namespace flysfm
