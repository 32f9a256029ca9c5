#pragma once

// Single-point least-squares matching (Gruen 1985; the paper's Sect. III-C,
// equations 1-3). A window of `window_size`^2 pixels around point1 in image 1
// (the template) is matched to image 2 under
//
//   I1(x1 + u, y1 + v) = h0 + h1 I2(a0 + a1 u + a2 v, b0 + b1 u + b2 v)
//
// with (u, v) the window offsets from the window's centre pixel; point1's
// match is (a0, b0) plus the affine part applied to point1's offset from that
// pixel. Positions follow OpenCV's convention: the centre of the top-left
// pixel is (0, 0), as for cv::KeyPoint.
//
// The solver is inverse compositional (Baker & Matthews 2004): each step is
// an affine increment of the template window, inverted and composed with the
// current warp, so that the Jacobian comes from the template alone and the
// normal matrix is built and factorised once per point; an iteration only
// samples image 2's values in the window.

#include <array>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core.hpp>

namespace flysfm {

// A grey image prepared for LSM: float, continuous, grey levels on the 8-bit
// scale (thresholds in LsmOptions are in those units). Convert each image once
// and match many points against it.
//
// It may also be a window of a larger image (core/lsm_image_store keeps only
// windows around the points of older images): its pixel (0, 0) is then the
// larger image's pixel `origin`, and positions given to and returned by LSM
// stay in the larger image's coordinates.
class LsmImage {
 public:
  LsmImage() = default;
  // Accepts a one-channel CV_8U or CV_32F image (CV_32F is taken as grey
  // levels on the 0..255 scale). Throws std::invalid_argument otherwise.
  explicit LsmImage(const cv::Mat& grey, int origin_x = 0, int origin_y = 0);
  // An image only to search with cubic-spline interpolation (an LsmMatcher's
  // image 2 with LsmInterpolation::kCubicSpline), which reads the spline
  // coefficients alone: the pixels are not kept, half the memory (a 24 MP
  // photo's level 0: 96 instead of 192 MB). Accepts what the constructor
  // does; such an image is no template, has no HalfResolution and no data().
  static LsmImage SplineOnly(const cv::Mat& grey);

  int width() const { return spline_.cols; }
  int height() const { return spline_.rows; }
  int origin_x() const { return origin_x_; }
  int origin_y() const { return origin_y_; }
  bool empty() const { return spline_.empty(); }
  bool has_pixels() const { return !pixels_.empty(); }
  const float* data() const { return pixels_.ptr<float>(); }
  const cv::Mat& pixels() const { return pixels_; }
  // Cubic B-spline coefficients of the pixels, same layout.
  const float* spline_coefficients() const { return spline_.ptr<float>(); }
  // Memory held (pixels and coefficients), for caches.
  std::size_t ByteSize() const {
    return pixels_.total() * pixels_.elemSize() + spline_.total() * spline_.elemSize();
  }

  // The image at half resolution (Gaussian 5x5, cv::pyrDown): a point (x, y)
  // here lies at (x / 2, y / 2) there. Whole images only (origin 0).
  LsmImage HalfResolution() const;

 private:
  // From `grey` (CV_8U or continuous CV_32F), strip by strip.
  void ComputeSplineCoefficients(const cv::Mat& grey);

  cv::Mat pixels_;  // CV_32FC1, continuous
  cv::Mat spline_;  // CV_32FC1, continuous
  int origin_x_ = 0;
  int origin_y_ = 0;
};

// `num_levels` images, level 0 the input, each next one at half resolution.
std::vector<LsmImage> BuildLsmPyramid(const cv::Mat& grey, int num_levels);

enum class LsmSolver {
  // Undamped inverse compositional steps.
  kGaussNewton,
  // Damped steps, accepted only when they lower the residual: slower but
  // more tolerant of a poor start.
  kLevenbergMarquardt,
};

enum class LsmInterpolation {
  // 4 taps: fast, but its smoothing varies with the sub-pixel phase and
  // biases positions by up to a few hundredths of a pixel (Schreier et al.
  // 2000, "Systematic errors in digital image correlation caused by
  // intensity interpolation").
  kBilinear,
  // Cubic B-spline on prefiltered coefficients (interpolating, 16 taps):
  // near-ideal response up to half the sampling rate, so the bias drops by
  // an order of magnitude for the same window.
  kCubicSpline,
};

struct LsmOptions {
  // Side of the square window in pixels; odd, 7..31 (paper: 15).
  int window_size = 15;
  LsmSolver solver = LsmSolver::kGaussNewton;
  LsmInterpolation interpolation = LsmInterpolation::kCubicSpline;
  // Converged once an update moves the refined point by less than
  // convergence_shift_px and every corner of the window by less than
  // convergence_corner_px (pixels). The corner bound (0.7 % of the affine
  // part on a 15x15 window) stops a premature end while the shape is still
  // changing; on noisy real windows the shape settles less tightly than
  // the point, hence the looser value.
  double convergence_shift_px = 0.01;
  double convergence_corner_px = 0.05;
  int max_iterations = 20;
  // Largest final distance of the refined position from the start (pixels).
  // Matches from SIFT are within about a pixel; farther moves mean LSM
  // slid onto another structure.
  double max_shift_px = 2.0;
  // Least normalised cross-correlation between the template and the warped
  // window at convergence. 0.8 keeps true matches under noise, blur and
  // slight non-affine distortion and rejects unrelated texture.
  double min_ncc = 0.8;
  // Least texture: the RMS grey-level gradient (grey levels per pixel) along
  // the weakest direction of the template (square root of the smaller
  // eigenvalue of its mean structure tensor) and the least grey-level
  // standard deviation of either window. 8-bit sensor noise is about 1 grey
  // level, so 1.5 keeps noise alone from passing for texture.
  double min_gradient = 1.5;
  double min_stddev = 2.0;
  // Largest condition number of the normal matrix with unit diagonal
  // (parameters scaled to comparable units): beyond it the parameters are
  // not determined by the window.
  double max_condition_number = 1e7;
  // The affine part may stretch the window at most this much either way
  // (singular values within [1 / s, s]); beyond it the iteration diverged.
  double max_affine_scale = 4.0;

  bool Check() const;
};

// Pixels around a template window's centre pixel that a window of an image
// must hold for LSM to match there as on the whole image: the window and the
// one-pixel border its gradients read, plus the context after which the cubic
// spline prefilter of a crop agrees with the whole image's (its boundary's
// influence decays by 2 - sqrt(3) = 0.27 a pixel: below 4e-4 of a grey-level
// step after 6 pixels).
int LsmTemplateReach(const LsmOptions& options);

enum class LsmStatus : int {
  kConverged = 0,
  kInvalidInput,    // a non-finite position or affine start
  kOutsideImage,    // a window (template or warped) leaves its image
  kLowTexture,      // too little texture in a window
  kDiverged,        // non-finite, degenerate or flipped parameters
  kNoConvergence,   // no update below the threshold within max_iterations
  kShiftTooLarge,   // final position beyond max_shift_px from the start
  kIllConditioned,  // singular or ill-conditioned normal matrix
  kLowCorrelation,  // final NCC below min_ncc
};
constexpr int kNumLsmStatus = 9;
const char* LsmStatusName(LsmStatus status);

// Failure counts by reason, indexed by LsmStatus.
struct LsmStatusCounts {
  std::array<int, kNumLsmStatus> counts{};
  void Add(LsmStatus status) { ++counts[static_cast<int>(status)]; }
  int operator[](LsmStatus status) const {
    return counts[static_cast<int>(status)];
  }
  int Total() const;
};

struct LsmResult {
  LsmStatus status = LsmStatus::kInvalidInput;
  // (a0, b0): the position in image 2 matching point1.
  Eigen::Vector2d point2 = Eigen::Vector2d::Zero();
  // Image-2 offset per window offset: [a1 a2; b1 b2].
  Eigen::Matrix2d affine = Eigen::Matrix2d::Identity();
  double h0 = 0.0;
  double h1 = 1.0;
  // NCC of the template and the warped window at the final parameters.
  double ncc = 0.0;
  // A-posteriori standard deviation of unit weight: RMS grey-level residual
  // with the redundancy n - 8.
  double sigma0 = 0.0;
  // Covariance of point2 (pixels^2): sigma0^2 times the inverse normal
  // matrix, carried from the template window into image 2 by the affine
  // part; set when converged.
  Eigen::Matrix2d point2_covariance = Eigen::Matrix2d::Zero();
  int num_iterations = 0;

  bool Converged() const { return status == LsmStatus::kConverged; }
};

// Matches points between image pairs. Holds the options and scratch buffers,
// so that per-point work allocates nothing; one instance per thread.
class LsmMatcher {
 public:
  // Throws std::invalid_argument when !options.Check().
  explicit LsmMatcher(const LsmOptions& options);

  const LsmOptions& options() const { return options_; }

  // Refines point2, the start in image 2, with `affine` the start of the
  // linear part (identity when the views are alike). The window is centred
  // on the whole pixel nearest to point1 + window_offset: an offset window
  // still containing point1 can avoid a depth edge or a flat patch beside
  // it, point1's match then following from the window's affine map.
  LsmResult Match(
      const LsmImage& image1, const Eigen::Vector2d& point1,
      const LsmImage& image2, const Eigen::Vector2d& point2,
      const Eigen::Matrix2d& affine = Eigen::Matrix2d::Identity(),
      const Eigen::Vector2d& window_offset = Eigen::Vector2d::Zero());

 private:
  struct Warp;
  struct TemplateWindow;
  struct Estimate;

  // The steps of Match. Those that can reject the point return false and
  // set `failure` to the reason.

  // Places the template (PlaceTemplate), copies it (CopyTemplate) and
  // rejects it when it has too little texture.
  bool SampleTemplate(const LsmImage& image1, const Eigen::Vector2d& point1,
                      const Eigen::Vector2d& window_offset,
                      TemplateWindow* window, LsmStatus* failure);
  // Centres the window on the whole pixel nearest to point1 + window_offset;
  // false when the window with its one-pixel border leaves image 1.
  bool PlaceTemplate(const LsmImage& image1, const Eigen::Vector2d& point1,
                     const Eigen::Vector2d& window_offset,
                     TemplateWindow* window) const;
  // Fills template_ and template_border_; returns the template's mean
  // structure tensor (central differences).
  Eigen::Matrix2d CopyTemplate(const LsmImage& image1,
                               const TemplateWindow& window);
  // The Jacobian (FillJacobian) and the normal matrix, factorised once for
  // every iteration of the point.
  bool BuildNormalEquations(const LsmImage& image1, TemplateWindow* window,
                            LsmStatus* failure);
  void FillJacobian(const LsmImage& image1, const TemplateWindow& window);
  // The start in image 2: the given position and affine part, the
  // radiometric parameters from the windows' means and contrasts.
  bool StartEstimate(const LsmImage& image2, const Eigen::Vector2d& point2,
                     const Eigen::Matrix2d& affine,
                     const TemplateWindow& window, Estimate* estimate,
                     LsmStatus* failure);
  // Steps until converged (kConverged), diverged (kDiverged), out of image 2
  // (kOutsideImage) or out of iterations (kNoConvergence).
  LsmStatus Iterate(const LsmImage& image2, const TemplateWindow& window,
                    Estimate* estimate, int* num_iterations);
  // The affine and radiometric update from the normal equations, damped by
  // `lambda` when `damped`; its geometric part is scaled by the gain.
  Eigen::Matrix<double, 8, 1> SolveScaledStep(
      const TemplateWindow& window, bool damped, double lambda,
      const Eigen::Matrix<double, 8, 1>& gradient) const;
  // Composes `warp` with the inverted update into `next`; false when either
  // is non-finite, flipped or stretched beyond max_affine_scale.
  bool ComposeStep(const Warp& warp,
                   const Eigen::Matrix<double, 8, 1>& scaled_step,
                   Warp* next) const;
  // How far a step moves the match, compared with convergence_shift_px.
  double StepShift(const Warp& warp, const Warp& next,
                   const Eigen::Vector2d& offset1) const;
  // The estimate's position, affine part, radiometry, NCC and sigma0.
  void WriteEstimate(const LsmImage& image2, const TemplateWindow& window,
                     const Estimate& estimate, LsmResult* result) const;
  // The status of a converged match (its shift from `start2`, the normal
  // matrix's condition, the NCC) and, when accepted, its covariance.
  LsmStatus JudgeConverged(const Eigen::Vector2d& start2,
                           const TemplateWindow& window,
                           const Estimate& estimate, LsmResult* result) const;

  // Samples the window under `warp` into warped_[buffer]; false when it
  // leaves the image.
  bool Sample(const LsmImage& image, const Warp& warp, int buffer);
  // Residuals of warped_[buffer] under `warp`, their product with the
  // Jacobian into `gradient`; returns their sum of squares in template grey
  // levels.
  double Evaluate(const Warp& warp, int buffer,
                  Eigen::Matrix<double, 8, 1>* gradient);

  LsmOptions options_;
  int radius_ = 0;
  int num_pixels_ = 0;
  // Window pixels in row order: the template, the template with a one-pixel
  // border (for its texture measure, row stride window_size + 2), the warped
  // window twice (a rejected damped step keeps the last accepted one), the
  // template-side Jacobian and the residuals.
  Eigen::VectorXf template_;
  std::vector<float> template_border_;
  Eigen::VectorXf warped_[2];
  Eigen::Matrix<float, Eigen::Dynamic, 8> jacobian_;
  Eigen::VectorXf residuals_;
};

// Normalised cross-correlation of two equally long windows; 0 when either is
// flat.
double NormalizedCrossCorrelation(const Eigen::Ref<const Eigen::VectorXf>& a,
                                  const Eigen::Ref<const Eigen::VectorXf>& b);

}  // namespace flysfm
