#include "lsm/densify.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

namespace flysfm {
namespace {

// The reference observations whose window fits in their image (with
// `margin` pixels around the point), those whose viewing ray to the point is
// closest in direction to the new image's first.
std::vector<int> ObservationsByDirection(const DensifyCandidate& candidate,
                                         const std::vector<LsmView>& references,
                                         const Eigen::Vector3d& new_center,
                                         double margin) {
  const Eigen::Vector3d new_ray = (candidate.xyz - new_center).normalized();
  std::vector<std::pair<double, int>> ranked;
  for (size_t i = 0; i < candidate.observations.size(); ++i) {
    const LsmView& reference = references[candidate.observations[i].view];
    const Eigen::Vector2d& point = candidate.observations[i].point2D;
    if (!(point.x() >= margin && point.y() >= margin &&
          point.x() <= reference.camera.width - 1 - margin &&
          point.y() <= reference.camera.height - 1 - margin)) {
      continue;
    }
    const Eigen::Vector3d ray =
        (candidate.xyz - ProjectionCenter(reference.cam_from_world))
            .normalized();
    ranked.emplace_back(-ray.dot(new_ray), static_cast<int>(i));
  }
  std::sort(ranked.begin(), ranked.end());
  std::vector<int> order;
  for (const auto& entry : ranked) order.push_back(entry.second);
  return order;
}

// d pixel / d point_in_cam, by central differences so that lens distortion
// is included.
Eigen::Matrix<double, 2, 3> ProjectionJacobian(const Camera& camera,
                                               const Eigen::Vector3d& in_cam) {
  Eigen::Matrix<double, 2, 3> jacobian;
  const double step = 1e-6 * in_cam.norm();
  for (int axis = 0; axis < 3; ++axis) {
    const Eigen::Vector3d delta = step * Eigen::Vector3d::Unit(axis);
    jacobian.col(axis) = (camera.ImgFromCam(in_cam + delta) -
                          camera.ImgFromCam(in_cam - delta)) /
                         (2.0 * step);
  }
  return jacobian;
}

// The initial pose corrected to the coarse matches: Gauss-Newton on the
// reprojection error over a small rotation and translation in the camera
// frame (x -> x + w x x + t), the matches beyond `inlier_px` left out. The
// first round gates by distance to the median shift, since a small pose
// error moves all projections nearly alike; coarse windows straddling depth
// edges land wrong and fall out there.
Rigid3d CorrectPose(const Camera& camera, const Rigid3d& cam_from_world,
                    const std::vector<Eigen::Vector3d>& points,
                    const std::vector<Eigen::Vector2d>& measured,
                    double inlier_px) {
  constexpr int kMinMatches = 12;
  const int n = static_cast<int>(points.size());
  if (n < kMinMatches) return cam_from_world;
  Eigen::Vector2d median_shift;
  for (int axis = 0; axis < 2; ++axis) {
    std::vector<double> values;
    for (int i = 0; i < n; ++i) {
      values.push_back(measured[i][axis] -
                       camera.ImgFromCam(cam_from_world * points[i])[axis]);
    }
    std::nth_element(values.begin(), values.begin() + n / 2, values.end());
    median_shift[axis] = values[n / 2];
  }
  Rigid3d pose = cam_from_world;
  for (int round = 0; round < 4; ++round) {
    Eigen::Matrix<double, 6, 6> normal = Eigen::Matrix<double, 6, 6>::Zero();
    Eigen::Matrix<double, 6, 1> gradient = Eigen::Matrix<double, 6, 1>::Zero();
    int used = 0;
    for (int i = 0; i < n; ++i) {
      const Eigen::Vector3d in_cam = pose * points[i];
      if (!(in_cam.z() > 0.0)) continue;
      const Eigen::Vector2d residual = measured[i] - camera.ImgFromCam(in_cam);
      const Eigen::Vector2d expected =
          round == 0 ? median_shift : Eigen::Vector2d::Zero();
      if ((residual - expected).norm() > inlier_px) continue;
      // d(x + w x x + t) / d(w, t) = [-[x]_x | I].
      Eigen::Matrix<double, 3, 6> motion;
      motion << 0.0, in_cam.z(), -in_cam.y(), 1.0, 0.0, 0.0, -in_cam.z(), 0.0,
          in_cam.x(), 0.0, 1.0, 0.0, in_cam.y(), -in_cam.x(), 0.0, 0.0, 0.0,
          1.0;
      const Eigen::Matrix<double, 2, 6> jacobian =
          ProjectionJacobian(camera, in_cam) * motion;
      normal += jacobian.transpose() * jacobian;
      gradient += jacobian.transpose() * residual;
      ++used;
    }
    if (used < kMinMatches) break;
    const Eigen::Matrix<double, 6, 1> step = normal.ldlt().solve(gradient);
    if (!step.allFinite()) break;
    const Eigen::Vector3d rotation = step.head<3>();
    const Eigen::Quaterniond increment(Eigen::AngleAxisd(
        rotation.norm(), rotation.norm() > 0.0
                             ? Eigen::Vector3d(rotation.normalized())
                             : Eigen::Vector3d::UnitX()));
    pose = Rigid3d(increment * pose.rotation,
                   increment * pose.translation + step.tail<3>());
  }
  return pose;
}

}  // namespace

bool DensifyOptions::Check() const {
  return lsm.Check() && num_pyramid_levels >= 1 && num_pyramid_levels <= 8 &&
         max_displacement_px > 0 && max_references_per_point >= 1 &&
         window_shift_px >= 0 && max_relative_sigma0 > 0 && min_depth >= 0;
}

Eigen::Matrix2d PredictAffine(const LsmView& reference,
                              const Eigen::Vector2d& reference_point,
                              const Eigen::Vector3d& xyz,
                              const LsmView& image) {
  const double depth = (reference.cam_from_world * xyz).z();
  const Rigid3d image_from_reference =
      image.cam_from_world * Inverse(reference.cam_from_world);
  const auto transfer = [&](const Eigen::Vector2d& pixel) {
    const Eigen::Vector3d in_reference =
        depth * reference.camera.CamFromImg(pixel).homogeneous();
    return image.camera.ImgFromCam(image_from_reference * in_reference);
  };
  Eigen::Matrix2d affine;
  for (int axis = 0; axis < 2; ++axis) {
    const Eigen::Vector2d step = Eigen::Vector2d::Unit(axis);
    affine.col(axis) = 0.5 * (transfer(reference_point + step) -
                              transfer(reference_point - step));
  }
  return affine;
}

DensifyResult Densify(const LsmView& image,
                      const std::vector<LsmView>& references,
                      const std::vector<DensifyCandidate>& candidates,
                      const DensifyOptions& options) {
  if (!options.Check()) throw std::invalid_argument("invalid DensifyOptions");
  const auto check_pyramid = [&](const LsmView& view) {
    if (static_cast<int>(view.pyramid.size()) < options.num_pyramid_levels) {
      throw std::invalid_argument("Densify: a view's pyramid has " +
                                  std::to_string(view.pyramid.size()) +
                                  " levels, the options need " +
                                  std::to_string(options.num_pyramid_levels));
    }
  };
  check_pyramid(image);
  for (const LsmView& reference : references) {
    if (!reference.window) check_pyramid(reference);
  }

  // Coarse levels: same window and tests, the shift bound scaled to the
  // level's pixels.
  std::vector<LsmMatcher> coarse_matchers;
  for (int level = 1; level < options.num_pyramid_levels; ++level) {
    LsmOptions coarse = options.lsm;
    coarse.max_shift_px = std::max(options.lsm.max_shift_px,
                                   options.max_displacement_px / (1 << level));
    coarse_matchers.emplace_back(coarse);
  }

  // The window's start shape for one reference observation.
  const auto start_affine = [&](const DensifyCandidate& candidate,
                                const DensifyObservation& observation) {
    if (!options.predict_affine) return Eigen::Matrix2d::Identity().eval();
    const Eigen::Matrix2d affine =
        PredictAffine(references[observation.view], observation.point2D,
                      candidate.xyz, image);
    if (!affine.allFinite() || !(affine.determinant() > 0.0)) {
      return Eigen::Matrix2d::Identity().eval();
    }
    return affine;
  };

  const auto in_image = [&](const Eigen::Vector2d& pixel, double margin) {
    return pixel.x() >= -margin && pixel.y() >= -margin &&
           pixel.x() <= image.camera.width - 1.0 + margin &&
           pixel.y() <= image.camera.height - 1.0 + margin;
  };

  // Pass 1: project, rank the references and, coarse to fine down to level
  // 1 from the closest one, estimate where each point lies.
  struct Attempt {
    int candidate;
    std::vector<int> observations;  // by viewing direction, closest first
    Eigen::Vector2d projection;
  };
  std::vector<Attempt> attempts;
  std::vector<Eigen::Vector3d> sample_points;
  std::vector<Eigen::Vector2d> sample_positions;
  DensifyResult result;
  result.num_candidates = static_cast<int>(candidates.size());
  const Eigen::Vector3d new_center = ProjectionCenter(image.cam_from_world);
  for (size_t c = 0; c < candidates.size(); ++c) {
    const DensifyCandidate& candidate = candidates[c];
    for (const DensifyObservation& observation : candidate.observations) {
      if (observation.view < 0 ||
          observation.view >= static_cast<int>(references.size())) {
        throw std::invalid_argument("Densify: observation of candidate " +
                                    std::to_string(c) +
                                    " names no reference view");
      }
    }
    const Eigen::Vector3d in_cam = image.cam_from_world * candidate.xyz;
    if (!(in_cam.z() > options.min_depth * in_cam.norm())) {
      ++result.num_behind;
      continue;
    }
    // Within the pose error of the image: whether it is inside is decided
    // with the corrected pose.
    const Eigen::Vector2d projection = image.camera.ImgFromCam(in_cam);
    if (!in_image(projection, options.max_displacement_px)) {
      ++result.num_outside;
      continue;
    }
    std::vector<int> ranked = ObservationsByDirection(
        candidate, references, new_center, options.lsm.window_size / 2 + 2);
    if (ranked.empty()) {
      ++result.num_no_reference;
      continue;
    }
    if (static_cast<int>(ranked.size()) > options.max_references_per_point) {
      ranked.resize(options.max_references_per_point);
    }
    const DensifyObservation& observation = candidate.observations[ranked[0]];
    const LsmView& reference = references[observation.view];
    attempts.push_back({static_cast<int>(c), std::move(ranked), projection});

    Eigen::Vector2d estimate = projection;
    Eigen::Matrix2d coarse_affine = start_affine(candidate, observation);
    bool found = false;
    for (int level = options.num_pyramid_levels - 1; level >= 1; --level) {
      const double scale = 1.0 / (1 << level);
      const LsmResult coarse = coarse_matchers[level - 1].Match(
          reference.Template(level, observation.point2D),
          scale * observation.point2D,
          image.pyramid[level], scale * estimate, coarse_affine);
      found = coarse.Converged();
      if (found) {
        estimate = coarse.point2 / scale;
        coarse_affine = coarse.affine;
      }
    }
    if (found) {
      sample_points.push_back(candidate.xyz);
      sample_positions.push_back(estimate);
    }
  }

  // Every point starts from the pose corrected to all coarse matches, not
  // from its own coarse match: coarse windows straddle depth edges and some
  // land wrong.
  const Rigid3d corrected =
      CorrectPose(image.camera, image.cam_from_world, sample_points,
                  sample_positions, options.lsm.max_shift_px);

  // Pass 2: full-resolution LSM from the corrected pose's projection
  // decides.
  LsmMatcher matcher(options.lsm);
  std::vector<Eigen::Vector2d> starts;
  {
    std::vector<Attempt> inside;
    for (Attempt& attempt : attempts) {
      const Eigen::Vector2d start = image.camera.ImgFromCam(
          corrected * candidates[attempt.candidate].xyz);
      if (!in_image(start, 0.0)) {
        ++result.num_outside;
        continue;
      }
      inside.push_back(std::move(attempt));
      starts.push_back(start);
    }
    attempts = std::move(inside);
  }
  const auto match = [&](size_t a, int rank,
                         const Eigen::Vector2d& window_offset) {
    const DensifyCandidate& candidate = candidates[attempts[a].candidate];
    const DensifyObservation& observation =
        candidate.observations[attempts[a].observations[rank]];
    return matcher.Match(references[observation.view].Template(0, observation.point2D),
                         observation.point2D, image.pyramid[0], starts[a],
                         start_affine(candidate, observation), window_offset);
  };
  // First the closest reference's window centred on the point, for every
  // point: the median sigma0 of those that converge is the residual a
  // window on one surface leaves in this image (noise, blur, interpolation).
  std::vector<LsmResult> centred;
  centred.reserve(attempts.size());
  std::vector<double> sigmas;
  for (size_t a = 0; a < attempts.size(); ++a) {
    centred.push_back(match(a, 0, Eigen::Vector2d::Zero()));
    if (centred.back().Converged()) sigmas.push_back(centred.back().sigma0);
  }
  // Too few for a median: no bound, and no shifted windows, which need it.
  constexpr int kMinForMedian = 10;
  const bool bounded = static_cast<int>(sigmas.size()) >= kMinForMedian;
  double max_sigma0 = std::numeric_limits<double>::infinity();
  if (bounded) {
    std::nth_element(sigmas.begin(), sigmas.begin() + sigmas.size() / 2,
                     sigmas.end());
    max_sigma0 = options.max_relative_sigma0 * sigmas[sigmas.size() / 2];
  }
  // Then, until a window converges with a residual within that bound, the
  // other references' centred windows and the shifted windows.
  const double shift =
      std::min(options.window_shift_px,
               static_cast<double>(options.lsm.window_size / 2));
  std::vector<Eigen::Vector2d> window_offsets = {Eigen::Vector2d::Zero()};
  if (bounded && shift > 0.0) {
    for (const double dx : {-shift, 0.0, shift}) {
      for (const double dy : {-shift, 0.0, shift}) {
        if (dx != 0.0 || dy != 0.0) window_offsets.emplace_back(dx, dy);
      }
    }
  }
  for (size_t a = 0; a < attempts.size(); ++a) {
    const Attempt& attempt = attempts[a];
    const int num_ranks = static_cast<int>(attempt.observations.size());
    LsmResult fine = centred[a];
    int used = -1;
    bool imprecise = false;
    for (const Eigen::Vector2d& window_offset : window_offsets) {
      for (int rank = 0; rank < num_ranks && used < 0; ++rank) {
        if (rank > 0 || window_offset != Eigen::Vector2d::Zero()) {
          fine = match(a, rank, window_offset);
        }
        if (!fine.Converged()) continue;
        if (fine.sigma0 > max_sigma0) {
          imprecise = true;
          continue;
        }
        used = rank;
      }
      if (used >= 0) break;
    }
    if (used < 0) {
      if (imprecise) {
        ++result.num_imprecise;
      } else {
        result.lsm_counts.Add(fine.status);
      }
      continue;
    }
    result.lsm_counts.Add(fine.status);
    if ((fine.point2 - attempt.projection).norm() >
        options.max_displacement_px) {
      ++result.num_displaced;
      continue;
    }
    const DensifyObservation& observation =
        candidates[attempt.candidate].observations[attempt.observations[used]];
    result.matches.push_back(
        {attempt.candidate, observation.view, fine.point2, fine});
  }
  return result;
}

}  // namespace flysfm
