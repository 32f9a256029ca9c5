#pragma once

// Bundle adjustment of a BundleProblem with Ceres: local (a hierarchical
// association tree's block, see association_tree.h) and global alike.

#include <functional>
#include <string>

#include "bundle/bundle_problem.h"

namespace flysfm {

class BundleAdjuster {
 public:
  struct Options {
    enum class Loss { kTrivial, kHuber, kCauchy };
    // Huber is convex, so a perturbed start converges as with least squares,
    // while an observation more than `loss_scale_px` off (twice the ~0.5 px
    // noise of SIFT refined by LSM) pulls with a capped force: gross outliers
    // left by matching cannot drag the block.
    Loss loss = Loss::kHuber;
    double loss_scale_px = 1.0;

    // Intrinsics refined for every camera of the problem (each through a
    // SubsetManifold of its parameter block); all fixed by default, as for a
    // calibrated camera and for the engine's small local blocks.
    bool refine_focal_length = false;
    bool refine_principal_point = false;
    bool refine_extra_params = false;
    // Safeguards of refined intrinsics, as bounds of the solve: a focal
    // length stays within this factor of its value at the start, and a
    // principal point within this fraction of the image size of the image
    // centre (where a lens puts it within a few per cent). A weakly
    // constrained block (two views, a flat scene, a critical motion) cannot
    // run off to a degenerate camera that the next images could not undo.
    double max_focal_length_change = 1.5;
    double max_principal_point_offset = 0.1;
    // The rolling-shutter readout time of every camera with a moving image
    // (BundleImage::IsMoving), within +-`max_readout_time_seconds` (a sensor
    // read bottom to top has a negative one). A video's frame interval
    // bounds it physically; 0.1 s is a 10 Hz camera's.
    bool refine_readout_time = false;
    double max_readout_time_seconds = 0.1;

    // What holds the 7-DoF similarity gauge of a free block.
    enum class Gauge {
      // Only the problem's constant poses (the caller's choice).
      kConstantPosesOnly,
      // Per block of images joined by refined points (disconnected blocks
      // are each free in 7 DoF): if none of the block's poses is constant,
      // its first image's pose is held; if fewer than two are, one
      // translation component of its first other image is held too (the one
      // most sensitive to scale about the held camera): exactly 7 DoF per
      // block, as COLMAP does for one. Adds nothing to a local block, whose
      // outermost ripple and outside observers are constant already.
      kMinimal,
    };
    Gauge gauge = Gauge::kMinimal;

    // Linear solver (docs/bundle.md, "Solver by size"). Iterative Schur
    // (Schur-Jacobi) when the points' tracks are long: beyond this
    // observation-weighted mean track length (sum n^2 / sum n over the
    // refined poses' observations of each point), since forming the Schur
    // complement costs n^2 per point and a conjugate-gradient step n.
    // Otherwise by the number of refined poses: dense Schur up to
    // `dense_schur_max_images`, SuiteSparse sparse Schur up to
    // `sparse_schur_max_images`, iterative Schur beyond.
    double iterative_schur_min_track_length = 50;
    int dense_schur_max_images = 300;
    int sparse_schur_max_images = 1000;

    int max_num_iterations = 50;
    double max_solver_time_seconds = 1e9;
    double function_tolerance = 1e-6;
    double gradient_tolerance = 1e-10;
    double parameter_tolerance = 1e-8;
    // The engine's loop is single-threaded; the second core decodes and
    // extracts features of the next image.
    int num_threads = 1;
    // Polled after each iteration; when it returns true the solve ends there,
    // its result usable (kNoConvergence). The engine's refinement between
    // shots gives way to a new image this way. Empty: never.
    std::function<bool()> should_stop;
    // Called after each iteration with its number (0: the start, before the
    // first step), for a progress line; it cannot stop the solve.
    std::function<void(int iteration)> on_iteration;

    bool Check() const;
  };

  enum class Termination {
    kConvergence,    // a tolerance was met
    kNoConvergence,  // iteration or time limit, or should_stop: the result is
                     // usable
    kFailure,        // numerical failure: the problem is left at its last
                     // accepted state
  };

  struct Summary {
    int num_images = 0;
    int num_free_images = 0;
    int num_points = 0;
    int num_free_points = 0;
    int num_residuals = 0;  // reprojection residual blocks actually added
    int num_pose_priors = 0;
    std::string linear_solver;

    // Ceres' cost, 1/2 sum of robustified squared residuals incl. priors.
    double initial_cost = 0;
    double final_cost = 0;
    // Mean pixel reprojection error over the observations in the solve.
    double initial_mean_reprojection_error_px = 0;
    double final_mean_reprojection_error_px = 0;

    int num_iterations = 0;
    double solver_time_seconds = 0;  // inside ceres::Solve
    double total_time_seconds = 0;   // including setup and priors
    Termination termination = Termination::kFailure;
    std::string message;

    bool IsSolutionUsable() const {
      return termination != Termination::kFailure;
    }
    std::string BriefReport() const;
  };

  explicit BundleAdjuster(const Options& options);

  // Refines the problem's free poses, points and intrinsics in place. A point
  // is constant when every image observing it has a constant pose;
  // observations that touch nothing free are left out.
  Summary Solve(BundleProblem* problem) const;

 private:
  Options options_;
};

}  // namespace flysfm
