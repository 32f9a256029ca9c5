#pragma once

// GRIC, the Geometric Robust Information Criterion (Torr 1997, "An
// assessment of information criteria for motion model selection"; Torr 1998,
// "Geometric motion segmentation and model selection"):
//
//   GRIC = sum_i rho(e_i^2 / sigma^2) + lambda1 d n + lambda2 k,
//   rho(x) = min(x, lambda3 (r - d)),
//
// with n matches, r = 4 the dimension of the data (two 2D points), d the
// dimension of the model's manifold in data space (F, E: 3; H: 2), k the
// number of model parameters (F: 7, E: 5, H: 8), e_i the 4D geometric
// residual (Sampson distance), sigma the noise standard deviation, and
// Torr's constants lambda1 = ln r, lambda2 = ln(r n), lambda3 = 2. The model
// with the smallest GRIC is selected: lambda1 d n penalizes a manifold of
// higher dimension (which fits noise better), lambda2 k the parameter count,
// and rho caps the cost of an outlier.

#include <vector>

namespace flysfm {

struct GricModel {
  int manifold_dim;  // d
  int num_params;    // k
};

inline constexpr GricModel kGricFundamental{3, 7};
inline constexpr GricModel kGricEssential{3, 5};
inline constexpr GricModel kGricHomography{2, 8};

inline constexpr int kGricDataDim = 4;    // r
inline constexpr double kGricLambda3 = 2.0;

// GRIC of a model over `squared_residuals` (e_i^2, units of sigma^2). +inf
// for sigma <= 0 or a non-finite sigma; non-finite residuals count as
// outliers (capped).
double Gric(const std::vector<double>& squared_residuals, double sigma,
            GricModel model, int data_dim = kGricDataDim);

// Robust noise estimate from the squared residuals of inliers of a model of
// codimension r - d: sigma^2 = median(e^2) / (median of chi^2 with r - d
// degrees of freedom). 0 when there are no finite residuals.
double EstimateNoiseSigma(std::vector<double> squared_residuals, int codimension);

}  // namespace flysfm
