#include "lsm/lsm.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <stdexcept>
#include <string>

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <opencv2/imgproc.hpp>

#include "geometry/check.h"

namespace flysfm {
namespace {

// Order of the parameters of a step: the template-side affine increment
// a0 a1 a2 b0 b1 b2 (x -> (a0 + (1 + a1) u + a2 v, b0 + b1 u + (1 + b2) v)),
// then the radiometric increment g0 g1.
using Vector8d = Eigen::Matrix<double, 8, 1>;
using Matrix8d = Eigen::Matrix<double, 8, 8>;
enum : int { kA0 = 0, kA1, kA2, kB0, kB1, kB2, kG0, kG1 };

// Bilinear interpolation; the caller guarantees 0 <= x < width - 1 and
// 0 <= y < height - 1.
inline float Bilinear(const float* data, int stride, double x, double y) {
  const int x0 = static_cast<int>(x);
  const int y0 = static_cast<int>(y);
  const float fx = static_cast<float>(x - x0);
  const float fy = static_cast<float>(y - y0);
  const float* p = data + static_cast<std::ptrdiff_t>(y0) * stride + x0;
  const float top = p[0] + fx * (p[1] - p[0]);
  const float bottom = p[stride] + fx * (p[stride + 1] - p[stride]);
  return top + fy * (bottom - top);
}

// Cubic B-spline weights of the taps at -1, 0, 1, 2 for a fraction t in
// [0, 1).
inline void SplineWeights(float t, float w[4]) {
  const float s = 1.f - t;
  const float t2 = t * t;
  w[0] = s * s * s * (1.f / 6.f);
  w[1] = (2.f / 3.f) - t2 + 0.5f * t2 * t;
  w[3] = t2 * t * (1.f / 6.f);
  w[2] = 1.f - w[0] - w[1] - w[3];
}

// Four floats in one SIMD register (GCC/Clang vector extension; SSE on
// x86-64, NEON on ARM): a row of the 4x4 spline footprint.
typedef float Float4 __attribute__((vector_size(16)));

inline Float4 Load4(const float* p) {
  Float4 v;
  std::memcpy(&v, p, sizeof(v));
  return v;
}

inline float Sum4(Float4 v) { return (v[0] + v[1]) + (v[2] + v[3]); }

// Cubic B-spline interpolation from prefiltered coefficients; the caller
// guarantees 1 <= x < width - 2 and 1 <= y < height - 2.
inline float CubicSpline(const float* coefficients, int stride, double x,
                         double y) {
  const int x0 = static_cast<int>(x);
  const int y0 = static_cast<int>(y);
  float wx[4], wy[4];
  SplineWeights(static_cast<float>(x - x0), wx);
  SplineWeights(static_cast<float>(y - y0), wy);
  const float* p =
      coefficients + static_cast<std::ptrdiff_t>(y0 - 1) * stride + x0 - 1;
  const Float4 rows = wy[0] * Load4(p) + wy[1] * Load4(p + stride) +
                      wy[2] * Load4(p + 2 * stride) +
                      wy[3] * Load4(p + 3 * stride);
  return Sum4(rows * Load4(wx));
}

// Pixels an interpolator reads beyond the sample's floor: before, after.
int MarginBefore(LsmInterpolation interpolation) {
  return interpolation == LsmInterpolation::kCubicSpline ? 1 : 0;
}
int MarginAfter(LsmInterpolation interpolation) {
  return interpolation == LsmInterpolation::kCubicSpline ? 2 : 1;
}

using RowArrayXXd = Eigen::Array<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

// In place, the cubic B-spline coefficients of each column of `c` (one signal
// per column, its samples down the rows), with mirror boundaries (Unser 1999,
// "Splines: a perfect fit for signal and image processing"; causal and
// anti-causal recursion). Recursing over rows of many columns at once runs
// the recursion in vector registers and reads memory in order.
void SplinePrefilterColumns(Eigen::Ref<RowArrayXXd> c) {
  const Eigen::Index n = c.rows();
  if (n < 2) return;
  const double z = std::sqrt(3.0) - 2.0;
  c *= 6.0;
  // |z|^12 < 1e-6: the mirrored causal sum is truncated there.
  const Eigen::Index horizon = std::min<Eigen::Index>(n, 12);
  double power = z;
  for (Eigen::Index i = 1; i < horizon; ++i, power *= z) c.row(0) += power * c.row(i);
  for (Eigen::Index i = 1; i < n; ++i) c.row(i) += z * c.row(i - 1);
  c.row(n - 1) = (z / (z * z - 1.0)) * (z * c.row(n - 2) + c.row(n - 1));
  for (Eigen::Index i = n - 2; i >= 0; --i) c.row(i) = z * (c.row(i + 1) - c.row(i));
}

// Whether the parallelogram of window offsets |u|, |v| <= reach mapped by
// (center, linear) lies where the interpolator may read.
bool InsideForSampling(const LsmImage& image, const Eigen::Vector2d& center,
                       const Eigen::Matrix2d& linear, int reach,
                       LsmInterpolation interpolation) {
  const double low = MarginBefore(interpolation);
  const double high_x = image.width() - MarginAfter(interpolation);
  const double high_y = image.height() - MarginAfter(interpolation);
  for (const int su : {-1, 1}) {
    for (const int sv : {-1, 1}) {
      const Eigen::Vector2d corner =
          center + linear * Eigen::Vector2d(su * reach, sv * reach);
      if (!(corner.x() >= low && corner.y() >= low && corner.x() < high_x &&
            corner.y() < high_y)) {
        return false;
      }
    }
  }
  return true;
}

// Samples (2 reach + 1)^2 points of the affinely mapped grid in row order.
template <typename Interpolator>
void SampleGridWith(const float* data, int stride,
                    const Eigen::Vector2d& center,
                    const Eigen::Matrix2d& linear, int reach,
                    Interpolator interpolate, float* values) {
  int k = 0;
  for (int v = -reach; v <= reach; ++v) {
    double x = center.x() - reach * linear(0, 0) + v * linear(0, 1);
    double y = center.y() - reach * linear(1, 0) + v * linear(1, 1);
    for (int u = -reach; u <= reach; ++u, ++k) {
      values[k] = interpolate(data, stride, x, y);
      x += linear(0, 0);
      y += linear(1, 0);
    }
  }
}

void MeanAndStddev(const Eigen::Ref<const Eigen::VectorXf>& values,
                   double* mean, double* stddev) {
  *mean = values.cast<double>().mean();
  *stddev = std::sqrt(std::max(
      0.0,
      values.cast<double>().squaredNorm() / values.size() - *mean * *mean));
}

void CheckLsmGrey(const cv::Mat& grey) {
  if (grey.empty() || grey.channels() != 1 ||
      (grey.depth() != CV_8U && grey.depth() != CV_32F)) {
    throw std::invalid_argument(
        "LSM needs a non-empty one-channel CV_8U or CV_32F image");
  }
}

// Rows (then columns) prefiltered at a time, so that the double-precision
// copy stays small for a whole photo.
constexpr Eigen::Index kSplineStrip = 64;

// Rows [y, y + height) of a CV_8U or CV_32F image, transposed (each row a
// column), in double precision.
template <typename T>
void StripFrom(const cv::Mat& grey, Eigen::Index y, Eigen::Index height, RowArrayXXd* strip) {
  strip->resize(grey.cols, height);
  const T* rows[kSplineStrip];
  FLYSFM_CHECK(height <= kSplineStrip);
  for (Eigen::Index r = 0; r < height; ++r) rows[r] = grey.ptr<T>(int(y + r));
  // Along the strip's rows, which are contiguous; the image rows read stay
  // in cache meanwhile.
  for (int x = 0; x < grey.cols; ++x) {
    double* out = &(*strip)(x, 0);
    for (Eigen::Index r = 0; r < height; ++r) out[r] = double(rows[r][x]);
  }
}

}  // namespace

LsmImage::LsmImage(const cv::Mat& grey, int origin_x, int origin_y)
    : origin_x_(origin_x), origin_y_(origin_y) {
  CheckLsmGrey(grey);
  grey.convertTo(pixels_, CV_32F);
  if (!pixels_.isContinuous()) pixels_ = pixels_.clone();
  ComputeSplineCoefficients(pixels_);
}

LsmImage LsmImage::SplineOnly(const cv::Mat& grey) {
  CheckLsmGrey(grey);
  LsmImage image;
  image.ComputeSplineCoefficients(grey);
  return image;
}

void LsmImage::ComputeSplineCoefficients(const cv::Mat& grey) {
  spline_.create(grey.rows, grey.cols, CV_32F);
  using RowArrayXXf = Eigen::Array<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
  Eigen::Map<RowArrayXXf> spline(spline_.ptr<float>(), spline_.rows, spline_.cols);
  // In strips of rows (transposed, so each row is a column), then of columns.
  RowArrayXXd strip;
  for (Eigen::Index y = 0; y < spline.rows(); y += kSplineStrip) {
    const Eigen::Index height = std::min(kSplineStrip, spline.rows() - y);
    if (grey.depth() == CV_8U) {
      StripFrom<std::uint8_t>(grey, y, height, &strip);
    } else {
      StripFrom<float>(grey, y, height, &strip);
    }
    SplinePrefilterColumns(strip);
    spline.middleRows(y, height) = strip.transpose().cast<float>();
  }
  for (Eigen::Index x = 0; x < spline.cols(); x += kSplineStrip) {
    const Eigen::Index width = std::min(kSplineStrip, spline.cols() - x);
    strip = spline.middleCols(x, width).cast<double>();
    SplinePrefilterColumns(strip);
    spline.middleCols(x, width) = strip.cast<float>();
  }
}

LsmImage LsmImage::HalfResolution() const {
  FLYSFM_CHECK(origin_x_ == 0 && origin_y_ == 0 && has_pixels());
  LsmImage half;
  cv::pyrDown(pixels_, half.pixels_);
  half.ComputeSplineCoefficients(half.pixels_);
  return half;
}

std::vector<LsmImage> BuildLsmPyramid(const cv::Mat& grey, int num_levels) {
  if (num_levels < 1) {
    throw std::invalid_argument("an LSM pyramid needs at least one level");
  }
  std::vector<LsmImage> levels;
  levels.reserve(num_levels);
  levels.emplace_back(grey);
  for (int level = 1; level < num_levels; ++level) {
    levels.push_back(levels.back().HalfResolution());
  }
  return levels;
}

int LsmTemplateReach(const LsmOptions& options) {
  constexpr int kSplineContext = 6;
  return options.window_size / 2 + 1 + kSplineContext;
}

bool LsmOptions::Check() const {
  return window_size >= 7 && window_size <= 31 && window_size % 2 == 1 &&
         convergence_shift_px > 0 &&
         convergence_corner_px >= convergence_shift_px && max_iterations >= 1 &&
         max_shift_px > 0 && min_ncc >= -1 && min_ncc <= 1 &&
         min_gradient >= 0 && min_stddev >= 0 && max_condition_number > 1 &&
         max_affine_scale > 1;
}

const char* LsmStatusName(LsmStatus status) {
  switch (status) {
    case LsmStatus::kConverged:
      return "converged";
    case LsmStatus::kInvalidInput:
      return "invalid_input";
    case LsmStatus::kOutsideImage:
      return "outside_image";
    case LsmStatus::kLowTexture:
      return "low_texture";
    case LsmStatus::kDiverged:
      return "diverged";
    case LsmStatus::kNoConvergence:
      return "no_convergence";
    case LsmStatus::kShiftTooLarge:
      return "shift_too_large";
    case LsmStatus::kIllConditioned:
      return "ill_conditioned";
    case LsmStatus::kLowCorrelation:
      return "low_correlation";
  }
  return "unknown";
}

int LsmStatusCounts::Total() const {
  int total = 0;
  for (const int count : counts) total += count;
  return total;
}

double NormalizedCrossCorrelation(const Eigen::Ref<const Eigen::VectorXf>& a,
                                  const Eigen::Ref<const Eigen::VectorXf>& b) {
  FLYSFM_CHECK(a.size() == b.size() && a.size() > 0);
  const double n = static_cast<double>(a.size());
  const double mean_a = a.cast<double>().mean();
  const double mean_b = b.cast<double>().mean();
  const double covariance =
      a.cast<double>().dot(b.cast<double>()) - n * mean_a * mean_b;
  const double variance_a =
      a.cast<double>().squaredNorm() - n * mean_a * mean_a;
  const double variance_b =
      b.cast<double>().squaredNorm() - n * mean_b * mean_b;
  const double denominator = std::sqrt(variance_a * variance_b);
  if (!(denominator > 0.0)) return 0.0;
  return covariance / denominator;
}

namespace {

bool IsValidStart(const Eigen::Vector2d& point1, const Eigen::Vector2d& point2,
                  const Eigen::Matrix2d& affine,
                  const Eigen::Vector2d& window_offset) {
  return point1.allFinite() && point2.allFinite() && affine.allFinite() &&
         window_offset.allFinite() && affine.determinant() > 0.0;
}

// The square root of the smaller eigenvalue of the symmetric 2x2 structure
// tensor, in closed form: the RMS gradient along the weakest direction.
double WeakestGradient(const Eigen::Matrix2d& structure) {
  const double half_trace = 0.5 * structure.trace();
  const double weakest =
      half_trace - std::sqrt(std::max(
                       0.0, half_trace * half_trace - structure.determinant()));
  return std::sqrt(std::max(0.0, weakest));
}

// The inverse of the normal matrix, false when the matrix is singular or its
// condition with unit diagonal, S = D N D, exceeds `max_condition_number`:
// the parameters' units (pixels, grey levels, ratios) then no longer matter.
// trace(S) trace(S^-1) = 8 sum_i N_ii (N^-1)_ii bounds the condition from
// above and costs only the inverse, which the covariance needs anyway; the
// eigenvalues are computed only when the bound exceeds the limit.
bool InvertWellConditioned(const Matrix8d& normal,
                           const Eigen::LDLT<Matrix8d>& normal_solver,
                           double max_condition_number, Matrix8d* inverse) {
  const Vector8d diagonal = normal.diagonal();
  *inverse = normal_solver.solve(Matrix8d::Identity());
  if (!(diagonal.minCoeff() > 0.0) || !inverse->allFinite()) return false;
  if (8.0 * diagonal.dot(inverse->diagonal()) <= max_condition_number) {
    return true;
  }
  const Vector8d scale = diagonal.cwiseSqrt().cwiseInverse();
  const Matrix8d scaled = scale.asDiagonal() * normal * scale.asDiagonal();
  const Eigen::SelfAdjointEigenSolver<Matrix8d> eigen(scaled,
                                                      Eigen::EigenvaluesOnly);
  const double smallest = eigen.eigenvalues()[0];
  return smallest > 0.0 &&
         !(eigen.eigenvalues()[7] / smallest > max_condition_number);
}

// The template-side shift of point1, dt + dA offset1, has covariance
// sigma0^2 P N^-1 P' in template units (the gain scaling of the columns and
// of the residual cancel); the composition carries it into image 2 as
// -A (dt + dA offset1).
Eigen::Matrix2d Point2Covariance(double sigma0, const Eigen::Matrix2d& linear,
                                 const Eigen::Vector2d& offset1,
                                 const Matrix8d& inverse) {
  Eigen::Matrix<double, 2, 8> point_jacobian =
      Eigen::Matrix<double, 2, 8>::Zero();
  point_jacobian.row(0).segment<3>(kA0) << 1.0, offset1.x(), offset1.y();
  point_jacobian.row(1).segment<3>(kB0) << 1.0, offset1.x(), offset1.y();
  return sigma0 * sigma0 * linear *
         (point_jacobian * inverse * point_jacobian.transpose()) *
         linear.transpose();
}

}  // namespace

// The current estimate: window offset (u, v) lies at translation +
// linear (u, v) in image 2, and image 2 = offset + gain * template there.
struct LsmMatcher::Warp {
  Eigen::Vector2d translation;
  Eigen::Matrix2d linear;
  double offset = 0.0;
  double gain = 1.0;

  Eigen::Vector2d Map(const Eigen::Vector2d& window) const {
    return translation + linear * window;
  }
};

// What one point's template gives every iteration: where it lies in image 1
// and its normal equations, factorised once.
struct LsmMatcher::TemplateWindow {
  // The whole pixel the window is centred on, in image 1's own pixels.
  int anchor_x = 0;
  int anchor_y = 0;
  // point1 from the anchor pixel.
  Eigen::Vector2d offset1;
  double mean = 0.0;
  double stddev = 0.0;
  Matrix8d normal;
  Eigen::LDLT<Matrix8d> normal_solver;
};

// The last accepted warp, the window sampled under it (warped_[buffer]), its
// cost and the gradient of the normal equations there. The converging step
// is accepted without sampling: the window and cost stay the previous warp's.
struct LsmMatcher::Estimate {
  Warp warp;
  int buffer = 0;
  double cost = 0.0;
  Vector8d gradient;
};

LsmMatcher::LsmMatcher(const LsmOptions& options) : options_(options) {
  if (!options.Check()) throw std::invalid_argument("invalid LsmOptions");
  radius_ = options.window_size / 2;
  num_pixels_ = options.window_size * options.window_size;
  const int bordered = (options.window_size + 2) * (options.window_size + 2);
  template_.resize(num_pixels_);
  template_border_.resize(bordered);
  for (Eigen::VectorXf& buffer : warped_) buffer.resize(num_pixels_);
  jacobian_.resize(num_pixels_, 8);
  residuals_.resize(num_pixels_);
}

bool LsmMatcher::Sample(const LsmImage& image, const Warp& warp, int buffer) {
  if (!InsideForSampling(image, warp.translation, warp.linear, radius_,
                         options_.interpolation)) {
    return false;
  }
  float* values = warped_[buffer].data();
  if (options_.interpolation == LsmInterpolation::kCubicSpline) {
    SampleGridWith(image.spline_coefficients(), image.width(), warp.translation,
                   warp.linear, radius_, CubicSpline, values);
  } else {
    FLYSFM_CHECK(image.has_pixels());
    SampleGridWith(image.data(), image.width(), warp.translation, warp.linear,
                   radius_, Bilinear, values);
  }
  return true;
}

double LsmMatcher::Evaluate(const Warp& warp, int buffer,
                            Eigen::Matrix<double, 8, 1>* gradient) {
  residuals_ = (warped_[buffer].array() - static_cast<float>(warp.offset)) -
               static_cast<float>(warp.gain) * template_.array();
  *gradient = (jacobian_.transpose() * residuals_).cast<double>();
  // In template grey levels: template - h0 - h1 image2 = -residual / gain.
  return static_cast<double>(residuals_.squaredNorm()) /
         (warp.gain * warp.gain);
}

LsmResult LsmMatcher::Match(const LsmImage& image1,
                            const Eigen::Vector2d& point1,
                            const LsmImage& image2,
                            const Eigen::Vector2d& point2,
                            const Eigen::Matrix2d& affine,
                            const Eigen::Vector2d& window_offset) {
  LsmResult result;
  result.point2 = point2;
  result.affine = affine;
  if (!IsValidStart(point1, point2, affine, window_offset)) {
    result.status = LsmStatus::kInvalidInput;
    return result;
  }
  TemplateWindow window;
  Estimate estimate;
  if (!SampleTemplate(image1, point1, window_offset, &window, &result.status) ||
      !BuildNormalEquations(image1, &window, &result.status) ||
      !StartEstimate(image2, point2, affine, window, &estimate,
                     &result.status)) {
    return result;
  }
  const LsmStatus iterated =
      Iterate(image2, window, &estimate, &result.num_iterations);
  // A diverged or lost match keeps its start; one out of iterations reports
  // where it got to, for the caller's statistics.
  if (iterated == LsmStatus::kDiverged ||
      iterated == LsmStatus::kOutsideImage) {
    result.status = iterated;
    return result;
  }
  WriteEstimate(image2, window, estimate, &result);
  result.status = iterated == LsmStatus::kConverged
                      ? JudgeConverged(point2, window, estimate, &result)
                      : iterated;
  return result;
}

bool LsmMatcher::SampleTemplate(const LsmImage& image1,
                                const Eigen::Vector2d& point1,
                                const Eigen::Vector2d& window_offset,
                                TemplateWindow* window, LsmStatus* failure) {
  if (!PlaceTemplate(image1, point1, window_offset, window)) {
    *failure = LsmStatus::kOutsideImage;
    return false;
  }
  const Eigen::Matrix2d structure = CopyTemplate(image1, *window);
  MeanAndStddev(template_, &window->mean, &window->stddev);
  if (!(WeakestGradient(structure) >= options_.min_gradient) ||
      !(window->stddev >= options_.min_stddev)) {
    *failure = LsmStatus::kLowTexture;
    return false;
  }
  return true;
}

bool LsmMatcher::PlaceTemplate(const LsmImage& image1,
                               const Eigen::Vector2d& point1,
                               const Eigen::Vector2d& window_offset,
                               TemplateWindow* window) const {
  // The template is read at whole pixels around the anchor, so that it is
  // not smoothed by interpolation; the affine map carries point1's offset
  // from the anchor into image 2.
  // Positions in each image's own pixels (a window's differ by its origin).
  const Eigen::Vector2d local1 =
      point1 - Eigen::Vector2d(image1.origin_x(), image1.origin_y());
  const int reach = radius_ + 1;
  const Eigen::Vector2d center1 = local1 + window_offset;
  if (!(center1.x() >= reach - 0.5 && center1.y() >= reach - 0.5 &&
        center1.x() < image1.width() - reach - 0.5 &&
        center1.y() < image1.height() - reach - 0.5)) {
    return false;
  }
  window->anchor_x = static_cast<int>(std::lround(center1.x()));
  window->anchor_y = static_cast<int>(std::lround(center1.y()));
  window->offset1 =
      local1 - Eigen::Vector2d(window->anchor_x, window->anchor_y);
  return true;
}

Eigen::Matrix2d LsmMatcher::CopyTemplate(const LsmImage& image1,
                                         const TemplateWindow& window) {
  const int reach = radius_ + 1;
  const int stride = options_.window_size + 2;
  FLYSFM_CHECK(image1.has_pixels());
  const float* pixels = image1.data();
  for (int v = -reach; v <= reach; ++v) {
    const float* row = pixels +
                       static_cast<std::ptrdiff_t>(window.anchor_y + v) *
                           image1.width() +
                       window.anchor_x - reach;
    std::copy(row, row + stride,
              template_border_.data() + (v + reach) * stride);
  }
  Eigen::Matrix2d structure = Eigen::Matrix2d::Zero();
  int k = 0;
  for (int v = 0; v < options_.window_size; ++v) {
    const float* row = template_border_.data() + (v + 1) * stride + 1;
    for (int u = 0; u < options_.window_size; ++u, ++k) {
      const float* s = row + u;
      template_[k] = s[0];
      const double gu = 0.5 * (s[1] - s[-1]);
      const double gv = 0.5 * (s[stride] - s[-stride]);
      structure(0, 0) += gu * gu;
      structure(0, 1) += gu * gv;
      structure(1, 1) += gv * gv;
    }
  }
  structure(1, 0) = structure(0, 1);
  structure /= num_pixels_;
  return structure;
}

bool LsmMatcher::BuildNormalEquations(const LsmImage& image1,
                                      TemplateWindow* window,
                                      LsmStatus* failure) {
  FillJacobian(image1, *window);
  window->normal = (jacobian_.transpose() * jacobian_).cast<double>();
  window->normal_solver.compute(window->normal);
  if (window->normal_solver.info() != Eigen::Success ||
      !window->normal_solver.isPositive()) {
    *failure = LsmStatus::kIllConditioned;
    return false;
  }
  return true;
}

// Inverse compositional Gauss-Newton (Baker & Matthews 2004, "Lucas-Kanade
// 20 years on"): each step is an affine increment of the template's window,
// inverted and composed with the warp. The Jacobian is then the template's
// and the normal matrix is built and factorised once per point; an
// iteration only samples image 2's values. The radiometric model is written
// image 2 = g0 + g1 * template so that its columns are template ones too.
// The template gradient is the exact derivative of image 1's cubic spline at
// whole pixels (B-spline derivative weights -1/2, 0, 1/2 across, 1/6, 2/3,
// 1/6 along).
void LsmMatcher::FillJacobian(const LsmImage& image1,
                              const TemplateWindow& window) {
  const float* coefficients = image1.spline_coefficients();
  const int width1 = image1.width();
  float* column[8];
  for (int c = 0; c < 8; ++c) column[c] = jacobian_.col(c).data();
  int k = 0;
  for (int v = -radius_; v <= radius_; ++v) {
    const float fv = static_cast<float>(v);
    const float* row = coefficients +
                       static_cast<std::ptrdiff_t>(window.anchor_y + v) *
                           width1 +
                       window.anchor_x;
    const float* above = row - width1;
    const float* below = row + width1;
    for (int u = -radius_; u <= radius_; ++u, ++k) {
      const float fu = static_cast<float>(u);
      const float gx = (1.f / 12.f) * ((above[u + 1] - above[u - 1]) +
                                       4.f * (row[u + 1] - row[u - 1]) +
                                       (below[u + 1] - below[u - 1]));
      const float gy = (1.f / 12.f) * ((below[u - 1] - above[u - 1]) +
                                       4.f * (below[u] - above[u]) +
                                       (below[u + 1] - above[u + 1]));
      column[kA0][k] = gx;
      column[kA1][k] = gx * fu;
      column[kA2][k] = gx * fv;
      column[kB0][k] = gy;
      column[kB1][k] = gy * fu;
      column[kB2][k] = gy * fv;
      column[kG0][k] = 1.f;
      column[kG1][k] = template_[k];
    }
  }
}

bool LsmMatcher::StartEstimate(const LsmImage& image2,
                               const Eigen::Vector2d& point2,
                               const Eigen::Matrix2d& affine,
                               const TemplateWindow& window,
                               Estimate* estimate, LsmStatus* failure) {
  const Eigen::Vector2d origin2(image2.origin_x(), image2.origin_y());
  Warp& warp = estimate->warp;
  warp.linear = affine;
  warp.translation = point2 - origin2 - affine * window.offset1;
  estimate->buffer = 0;
  if (!Sample(image2, warp, estimate->buffer)) {
    *failure = LsmStatus::kOutsideImage;
    return false;
  }
  // Radiometric start from the windows' means and contrasts, so that the
  // first steps are spent on geometry.
  double warped_mean = 0.0;
  double warped_stddev = 0.0;
  MeanAndStddev(warped_[estimate->buffer], &warped_mean, &warped_stddev);
  if (!(warped_stddev >= options_.min_stddev)) {
    *failure = LsmStatus::kLowTexture;
    return false;
  }
  warp.gain = warped_stddev / window.stddev;
  warp.offset = warped_mean - warp.gain * window.mean;
  estimate->cost = Evaluate(warp, estimate->buffer, &estimate->gradient);
  return true;
}

LsmStatus LsmMatcher::Iterate(const LsmImage& image2,
                              const TemplateWindow& window, Estimate* estimate,
                              int* num_iterations) {
  const bool damped = options_.solver == LsmSolver::kLevenbergMarquardt;
  double lambda = 1e-3;
  Vector8d next_gradient;
  for (int iteration = 1; iteration <= options_.max_iterations; ++iteration) {
    *num_iterations = iteration;
    const Vector8d scaled_step =
        SolveScaledStep(window, damped, lambda, estimate->gradient);
    Warp next;
    if (!ComposeStep(estimate->warp, scaled_step, &next)) {
      return LsmStatus::kDiverged;
    }
    // The last step is applied without sampling its window again: it moves
    // the window by less than the threshold, which changes neither the NCC
    // nor sigma0 measurably, and saves a fifth of the sampling.
    if (StepShift(estimate->warp, next, window.offset1) <
        options_.convergence_shift_px) {
      estimate->warp = next;
      return LsmStatus::kConverged;
    }
    const int spare = 1 - estimate->buffer;
    if (!Sample(image2, next, spare)) return LsmStatus::kOutsideImage;
    const double next_cost = Evaluate(next, spare, &next_gradient);
    if (damped && !(next_cost < estimate->cost)) {
      lambda *= 10.0;
      continue;
    }
    if (damped) lambda = std::max(lambda / 10.0, 1e-9);
    estimate->warp = next;
    estimate->buffer = spare;
    estimate->cost = next_cost;
    std::swap(estimate->gradient, next_gradient);
  }
  return LsmStatus::kNoConvergence;
}

// The gain scales the geometric columns: with D = diag(g1 x 6, 1, 1) the
// system is (D N D) step = D J' e, i.e. N (D step) = J' e; damping the
// diagonal commutes with D. The step returned is D step.
Eigen::Matrix<double, 8, 1> LsmMatcher::SolveScaledStep(
    const TemplateWindow& window, bool damped, double lambda,
    const Eigen::Matrix<double, 8, 1>& gradient) const {
  if (!damped) return window.normal_solver.solve(gradient);
  Matrix8d system = window.normal;
  system.diagonal() *= 1.0 + lambda;
  return system.ldlt().solve(gradient);
}

bool LsmMatcher::ComposeStep(const Warp& warp,
                             const Eigen::Matrix<double, 8, 1>& scaled_step,
                             Warp* next) const {
  const double to_geometric = 1.0 / warp.gain;
  Eigen::Matrix2d increment;
  increment << 1.0 + to_geometric * scaled_step[kA1],
      to_geometric * scaled_step[kA2], to_geometric * scaled_step[kB1],
      1.0 + to_geometric * scaled_step[kB2];
  const Eigen::Vector2d increment_shift(to_geometric * scaled_step[kA0],
                                        to_geometric * scaled_step[kB0]);
  if (!scaled_step.allFinite() || !(increment.determinant() > 0.0)) {
    return false;
  }
  // W(x) <- W(increment^-1(x)).
  next->linear = warp.linear * increment.inverse();
  next->translation = warp.translation - next->linear * increment_shift;
  next->offset = warp.offset + scaled_step[kG0];
  next->gain = warp.gain + scaled_step[kG1];
  if (!next->linear.allFinite() || !next->translation.allFinite() ||
      !std::isfinite(next->offset) || !(next->gain > 0.0) ||
      !(next->linear.determinant() > 0.0)) {
    return false;
  }
  const Eigen::Vector2d singular_values =
      Eigen::JacobiSVD<Eigen::Matrix2d>(next->linear).singularValues();
  return !(singular_values[0] > options_.max_affine_scale ||
           singular_values[1] < 1.0 / options_.max_affine_scale);
}

// Converged when the point has settled and the window's shape has too: the
// point's shift alone can stall while the affine part is far off. The
// corners' largest shift is scaled to the point's threshold.
double LsmMatcher::StepShift(const Warp& warp, const Warp& next,
                             const Eigen::Vector2d& offset1) const {
  const double point_shift = (next.Map(offset1) - warp.Map(offset1)).norm();
  double corner_shift = 0.0;
  for (const double su : {-radius_, radius_}) {
    for (const double sv : {-radius_, radius_}) {
      const Eigen::Vector2d corner(su, sv);
      corner_shift = std::max(corner_shift,
                              (next.Map(corner) - warp.Map(corner)).norm());
    }
  }
  return std::max(point_shift, corner_shift * options_.convergence_shift_px /
                                   options_.convergence_corner_px);
}

void LsmMatcher::WriteEstimate(const LsmImage& image2,
                               const TemplateWindow& window,
                               const Estimate& estimate,
                               LsmResult* result) const {
  const Eigen::Vector2d origin2(image2.origin_x(), image2.origin_y());
  const Warp& warp = estimate.warp;
  result->affine = warp.linear;
  result->point2 = warp.Map(window.offset1) + origin2;
  result->h0 = -warp.offset / warp.gain;
  result->h1 = 1.0 / warp.gain;
  result->ncc = NormalizedCrossCorrelation(template_, warped_[estimate.buffer]);
  result->sigma0 = std::sqrt(estimate.cost / (num_pixels_ - 8));
}

LsmStatus LsmMatcher::JudgeConverged(const Eigen::Vector2d& start2,
                                     const TemplateWindow& window,
                                     const Estimate& estimate,
                                     LsmResult* result) const {
  if ((result->point2 - start2).norm() > options_.max_shift_px) {
    return LsmStatus::kShiftTooLarge;
  }
  Matrix8d inverse;
  if (!InvertWellConditioned(window.normal, window.normal_solver,
                             options_.max_condition_number, &inverse)) {
    return LsmStatus::kIllConditioned;
  }
  if (!(result->ncc >= options_.min_ncc)) return LsmStatus::kLowCorrelation;
  result->point2_covariance = Point2Covariance(
      result->sigma0, estimate.warp.linear, window.offset1, inverse);
  return LsmStatus::kConverged;
}

}  // namespace flysfm
