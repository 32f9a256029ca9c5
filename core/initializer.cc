#include "core/initializer.h"

#include <algorithm>
#include <stdexcept>

#include "geometry/binary_io.h"
#include "geometry/essential_matrix.h"
#include "geometry/fundamental_matrix.h"
#include "geometry/triangulation.h"

namespace flysfm {

bool Initializer::Options::Check() const {
  return min_num_inliers >= 5 && min_tri_angle_deg >= 0 && min_num_points >= 2 &&
         min_point_angle_deg >= 0 && max_error_px > 0 && focal_from_fundamental.Check();
}

Initializer::Initializer(const Options& options) : options_(options) {
  if (!options_.Check()) throw std::invalid_argument("invalid initializer options");
}

void Initializer::AddPair(image_t image_id1, image_t image_id2, const TwoViewGeometry& geometry,
                          bool intrinsics_known) {
  if (!geometry.has_pose || geometry.config == TwoViewConfiguration::kPanoramic) return;
  if (intrinsics_known && geometry.config == TwoViewConfiguration::kUncalibrated) return;
  const bool fixes_focal = geometry.config == TwoViewConfiguration::kCalibrated ||
                          geometry.config == TwoViewConfiguration::kUncalibrated;
  pairs_.push_back({image_id1, image_id2, geometry.cam2_from_cam1,
                    fixes_focal ? geometry.F : Eigen::Matrix3d::Zero()});
}

int Initializer::CorrectFocalLength(const Reconstruction& reconstruction, camera_t camera_id,
                                    double* focal_length) const {
  std::vector<Eigen::Matrix3d> fundamentals;
  for (const Candidate& candidate : pairs_) {
    if (candidate.F.isZero() ||
        reconstruction.image(candidate.image_id1).camera_id != camera_id ||
        reconstruction.image(candidate.image_id2).camera_id != camera_id) {
      continue;
    }
    fundamentals.push_back(candidate.F);
  }
  const Camera& camera = reconstruction.camera(camera_id);
  const Eigen::Matrix3d K = CalibrationMatrix(camera);
  return FocalFromFundamentals(fundamentals, K.topRightCorner<2, 1>(),
                               std::max(camera.width, camera.height), camera.MeanFocalLength(),
                               options_.focal_from_fundamental, focal_length);
}

void Initializer::RecomputePoses(const Reconstruction& reconstruction,
                                 const MatchStore& matches) {
  std::vector<Candidate> kept;
  for (Candidate& candidate : pairs_) {
    const Image& image1 = reconstruction.image(candidate.image_id1);
    const Image& image2 = reconstruction.image(candidate.image_id2);
    const Camera& camera1 = reconstruction.camera(image1.camera_id);
    const Camera& camera2 = reconstruction.camera(image2.camera_id);
    std::vector<Eigen::Vector2d> x1, x2;
    for (const FeatureMatch& match :
         matches.Matches(candidate.image_id1, candidate.image_id2)) {
      x1.push_back(camera1.CamFromImg(image1.points2D[match.idx1].xy));
      x2.push_back(camera2.CamFromImg(image2.points2D[match.idx2].xy));
    }
    if (!candidate.F.isZero()) {
      const Eigen::Matrix3d E = EssentialFromFundamental(
          candidate.F, CalibrationMatrix(camera1), CalibrationMatrix(camera2));
      if (RelativePoseFromEssential(E, x1, x2, &candidate.cam2_from_cam1) == 0) continue;
    }
    RefineRelativePose(x1, x2, {}, &candidate.cam2_from_cam1);
    kept.push_back(candidate);
  }
  pairs_ = std::move(kept);
}

void Initializer::ForgetRegistered(const Reconstruction& reconstruction) {
  pairs_.erase(std::remove_if(pairs_.begin(), pairs_.end(),
                              [&](const Candidate& candidate) {
                                return reconstruction.image(candidate.image_id1).IsRegistered() ||
                                       reconstruction.image(candidate.image_id2).IsRegistered();
                              }),
               pairs_.end());
}

std::vector<InitialPair> Initializer::RankPairs(const Reconstruction& reconstruction,
                                                const MatchStore& matches,
                                                image_t image_id) const {
  std::vector<InitialPair> ranked;
  for (const Candidate& candidate : pairs_) {
    if (image_id != kInvalidImageId && candidate.image_id1 != image_id &&
        candidate.image_id2 != image_id) {
      continue;
    }
    if (reconstruction.image(candidate.image_id1).IsRegistered() ||
        reconstruction.image(candidate.image_id2).IsRegistered()) {
      continue;
    }
    const std::vector<FeatureMatch> verified =
        matches.Matches(candidate.image_id1, candidate.image_id2);
    if (int(verified.size()) < options_.min_num_inliers) continue;
    const Image& image1 = reconstruction.image(candidate.image_id1);
    const Image& image2 = reconstruction.image(candidate.image_id2);
    const Camera& camera1 = reconstruction.camera(image1.camera_id);
    const Camera& camera2 = reconstruction.camera(image2.camera_id);
    const Rigid3d cam1_from_world;
    const Matrix3x4d projection1 = cam1_from_world.ToMatrix();
    const Matrix3x4d projection2 = candidate.cam2_from_cam1.ToMatrix();
    const Eigen::Vector3d center1 = Eigen::Vector3d::Zero();
    const Eigen::Vector3d center2 = ProjectionCenter(candidate.cam2_from_cam1);
    std::vector<double> angles;
    for (const FeatureMatch& match : verified) {
      const Eigen::Vector2d& pixel1 = image1.points2D[match.idx1].xy;
      const Eigen::Vector2d& pixel2 = image2.points2D[match.idx2].xy;
      const std::optional<Eigen::Vector3d> point = TriangulatePoint(
          projection1, projection2, camera1.CamFromImg(pixel1), camera2.CamFromImg(pixel2));
      if (!point || !HasPositiveDepth(projection1, *point) ||
          !HasPositiveDepth(projection2, *point)) {
        continue;
      }
      const double angle = TriangulationAngleDeg(center1, center2, *point);
      if (angle < options_.min_point_angle_deg ||
          (camera1.ImgFromCam(*point) - pixel1).norm() > options_.max_error_px ||
          (camera2.ImgFromCam(candidate.cam2_from_cam1 * *point) - pixel2).norm() >
              options_.max_error_px) {
        continue;
      }
      angles.push_back(angle);
    }
    if (int(angles.size()) < options_.min_num_points) continue;
    std::nth_element(angles.begin(), angles.begin() + angles.size() / 2, angles.end());
    const double median = angles[angles.size() / 2];
    if (median < options_.min_tri_angle_deg) continue;
    ranked.push_back({candidate.image_id1, candidate.image_id2, candidate.cam2_from_cam1,
                      int(angles.size()), median});
  }
  std::stable_sort(ranked.begin(), ranked.end(), [](const auto& a, const auto& b) {
    return a.num_points > b.num_points;
  });
  return ranked;
}

void Initializer::Discard(const InitialPair& pair) {
  pairs_.erase(std::remove_if(pairs_.begin(), pairs_.end(),
                              [&](const Candidate& candidate) {
                                return candidate.image_id1 == pair.image_id1 &&
                                       candidate.image_id2 == pair.image_id2;
                              }),
               pairs_.end());
}

void Initializer::Write(std::ostream& out) const {
  WriteCount(out, pairs_.size());
  for (const Candidate& pair : pairs_) {
    WriteValue(out, pair.image_id1);
    WriteValue(out, pair.image_id2);
    WriteRigid3d(out, pair.cam2_from_cam1);
    for (int k = 0; k < 9; ++k) WriteValue(out, pair.F(k));
  }
}

void Initializer::Read(std::istream& in) {
  pairs_.resize(ReadCount(in, "initial pairs", std::size_t(1) << 24));
  for (Candidate& pair : pairs_) {
    pair.image_id1 = ReadValue<image_t>(in, "initial pair");
    pair.image_id2 = ReadValue<image_t>(in, "initial pair");
    pair.cam2_from_cam1 = ReadRigid3d(in, "initial pair pose");
    for (int k = 0; k < 9; ++k) pair.F(k) = ReadValue<double>(in, "initial pair F");
  }
}

}  // namespace flysfm
