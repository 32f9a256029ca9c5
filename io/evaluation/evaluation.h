#pragma once

// Accuracy against ground truth: camera centres compared after the similarity
// (Sim3, Umeyama) that best aligns the estimate to the reference, the
// convention for monocular methods (TUM's ATE) and for Strecha's benchmark.

#include <map>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "core/scene/reconstruction.h"
#include "geometry/sim3d.h"
#include "io/formats/trajectory.h"

namespace flysfm {

struct PositionErrors {
  int num_compared = 0;
  double rmse = 0;
  double mean = 0;
  double median = 0;
  double max = 0;
  // Maps the estimate's frame onto the reference's.
  Sim3d reference_from_estimate;
};

// nullopt for fewer than 3 pairs or a degenerate (collinear) configuration.
std::optional<PositionErrors> ComparePositionsAfterSim3(
    const std::vector<Eigen::Vector3d>& estimated,
    const std::vector<Eigen::Vector3d>& reference);

// The registered images' camera centres against reference centres given by
// image name (images without one are left out), after Sim3 alignment.
std::optional<PositionErrors> CompareCentersByName(
    const Reconstruction& reconstruction,
    const std::map<std::string, Eigen::Vector3d>& reference_centers);

// How well a model's observations fit true poses, beside how well they fit
// the model's own: each point is triangulated again from its observations
// with the true poses and the model's intrinsics (maximum likelihood:
// least squares in pixels), and its observations' reprojection errors are
// taken then. Exact poses fit the observations as well as the model's own
// (which have 6 parameters per image more to fit them with, a difference
// of that share of the redundancy); poses with errors of their own fit
// them worse. Tells whether a ground truth is exact enough to rank two
// models whose centre errors differ by less than a few tenths of the error.
struct PoseFit {
  int num_observations = 0;  // of points seen by two or more images with a true pose
  double model_median_px = 0;
  double truth_median_px = 0;
  double model_rms_px = 0;
  double truth_rms_px = 0;
};

// nullopt when no point has two observations in images with a true pose.
// Intrinsics should be the true ones (a model given its calibration).
std::optional<PoseFit> FitObservationsToPoses(
    const Reconstruction& reconstruction,
    const std::map<std::string, Rigid3d>& true_cam_from_world);

struct TrajectoryEvaluation {
  int num_estimated = 0;
  int num_reference = 0;
  int num_associated = 0;
  // Absent when too few poses associate to align.
  std::optional<PositionErrors> ate;

  // The report as text lines, the last a JSON object of the same figures.
  std::string Report() const;
};

// TUM's absolute trajectory error: poses associated by timestamp (within
// `max_time_difference` seconds), then ComparePositionsAfterSim3 on their
// camera centres.
TrajectoryEvaluation EvaluateTrajectory(const std::vector<StampedPose>& estimated,
                                        const std::vector<StampedPose>& reference,
                                        double max_time_difference = 0.02);

}  // namespace flysfm
