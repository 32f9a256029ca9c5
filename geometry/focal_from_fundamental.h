#pragma once

// The focal length a set of fundamental matrices agree on, for cameras that
// share it, with square pixels, no skew and a known principal point: for the
// true focal length f, E = K^T F K (K = diag(f, f, 1) about the principal
// point) is essential, its two non-zero singular values equal (Mendonca and
// Cipolla 1999). A pair fixes f only when its optical axes do not meet
// (Bougnoux 1998): where they do, every f makes E essential, and the gap has
// no minimum to prefer.

#include <vector>

#include <Eigen/Core>

namespace flysfm {

// (s1 - s2) / (s1 + s2) of E = K^T F K's two largest singular values: 0 when E
// is essential, at most 1. F maps pixels of image 1 to lines in image 2.
double EssentialSingularValueGap(const Eigen::Matrix3d& F,
                                 const Eigen::Vector2d& principal_point,
                                 double focal_length);

struct FocalFromFundamentalOptions {
  // Range searched, in multiples of the image's longer side (a 14 mm lens on
  // a full-frame body is 0.4, a 600 mm one 17), sampled geometrically.
  double min_focal_length_factor = 0.25;
  double max_focal_length_factor = 25;
  int num_samples = 240;
  // The minimum replaces the reference focal length only when the mean gap
  // there is at least `min_contrast` times the minimum's, and more than
  // `min_gap_rise` above it: a pair whose axes meet, or F's noise, leaves a
  // floor too flat to prefer one focal length to another.
  double min_contrast = 3.0;
  double min_gap_rise = 1e-3;

  bool Check() const;
};

// The focal length minimising the mean gap over `fundamentals` (all sharing
// the camera, `principal_point` and `longer_side`, the image's longer side in
// pixels), when the data clearly prefer it to
// `reference_focal_length` (a guess to be replaced). Returns 1 and sets
// *focal_length then, else 0 (no F, a minimum on the range's boundary or not
// clearly below the reference's gap, non-finite input).
int FocalFromFundamentals(const std::vector<Eigen::Matrix3d>& fundamentals,
                          const Eigen::Vector2d& principal_point, double longer_side,
                          double reference_focal_length,
                          const FocalFromFundamentalOptions& options, double* focal_length);

}  // namespace flysfm
