#pragma once

// One generic RANSAC for every estimator in flysfm: MSAC scoring (truncated
// squared error), adaptive number of iterations from the inlier ratio and the
// confidence, local optimisation (LO-RANSAC, Chum et al. 2003) of every new
// best model by iterated least squares on its inliers, an optional final
// refinement, and a seeded random generator so runs are reproducible.
//
// An Estimator provides:
//   using Model = ...;
//   static constexpr int kMinSampleSize = ...;
//   int NumData() const;
//   // Models from a minimal sample of kMinSampleSize distinct indices
//   // (none for a degenerate sample).
//   void MinimalSolve(const std::vector<int>& sample,
//                     std::vector<Model>* models) const;
//   // Models from >= kMinSampleSize indices (least squares); `initial` is
//   // the current best model, which the estimator may use or ignore.
//   void NonMinimalSolve(const std::vector<int>& indices, const Model& initial,
//                        std::vector<Model>* models) const;
//   // Final refinement on the inliers (e.g. non-linear least squares);
//   // returns false when it failed and *model is unchanged.
//   bool Refine(const std::vector<int>& inliers, Model* model) const;
//   // Squared error of datum `index` under `model`, in the units of
//   // RansacOptions::max_error squared. NaN or inf means outlier.
//   double SquaredError(const Model& model, int index) const;

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <random>
#include <string>
#include <vector>

namespace flysfm {

struct RansacOptions {
  // Inlier threshold on the error (square root of SquaredError), in the
  // estimator's units (e.g. pixels). Must be > 0.
  double max_error = 1.0;
  // Stop once an all-inlier sample has been drawn with this probability,
  // given the best model's inlier ratio. In (0, 1).
  double confidence = 0.999;
  // Bounds on the number of samples drawn.
  int min_iterations = 0;
  int max_iterations = 10000;
  // Models explaining fewer than this fraction of the data are not worth
  // searching for: never draw more samples than finding one with this inlier
  // ratio takes (at `confidence`). 0 leaves only max_iterations. In [0, 1].
  double min_inlier_ratio = 0.0;
  // LO-RANSAC: each new best model is improved by up to
  // `lo_max_iterations` rounds of least squares on its inliers.
  bool local_optimization = true;
  int lo_max_iterations = 10;
  // Estimator::Refine on the final inliers, repeated while it improves the
  // score (at most `max_refinements` times).
  bool final_refinement = true;
  int max_refinements = 3;
  // Seed of the sampler: equal seeds and data give equal results.
  std::uint32_t seed = 0;

  // True when every option is in its documented range; the functions taking
  // these options throw std::invalid_argument naming the bad one otherwise.
  bool Check() const;
};

template <typename Model>
struct RansacResult {
  bool success = false;
  Model model{};
  // inlier_mask[i] != 0 when datum i is an inlier of `model`.
  std::vector<char> inlier_mask;
  int num_inliers = 0;
  // Samples drawn.
  int num_iterations = 0;
  // MSAC cost: sum over the data of min(error^2, max_error^2).
  double score = std::numeric_limits<double>::infinity();
};

// Empty when the options are valid, else a message naming the bad option.
std::string RansacOptionsProblem(const RansacOptions& options);
// Throws std::invalid_argument(problem) unless `problem` is empty.
void ThrowIfInvalid(const std::string& problem);

// Samples needed to draw one all-inlier sample with probability `confidence`
// when num_inliers of num_data are inliers: log(1 - p) / log(1 - w^m).
// Saturates at std::numeric_limits<int>::max().
int RansacRequiredIterations(int num_inliers, int num_data, int sample_size,
                             double confidence);

namespace internal {

template <typename Estimator>
class RansacRunner {
 public:
  using Model = typename Estimator::Model;
  static constexpr int kSampleSize = Estimator::kMinSampleSize;

  RansacRunner(const Estimator& estimator, const RansacOptions& options)
      : estimator_(estimator),
        options_(options),
        num_data_(estimator.NumData()),
        threshold2_(options.max_error * options.max_error),
        rng_(options.seed) {}

  RansacResult<Model> Run() {
    RansacResult<Model> result;
    if (num_data_ < kSampleSize || num_data_ <= 0) return result;
    order_.resize(num_data_);
    for (int i = 0; i < num_data_; ++i) order_[i] = i;
    std::shuffle(order_.begin(), order_.end(), rng_);
    double best_score = std::numeric_limits<double>::infinity();
    Model best_model{};
    int best_inliers = 0;
    bool have_model = false;
    int max_trials = options_.max_iterations;
    if (options_.min_inlier_ratio > 0) {
      max_trials = std::min(
          max_trials,
          std::max(options_.min_iterations,
                   RansacRequiredIterations(
                       static_cast<int>(std::ceil(options_.min_inlier_ratio * num_data_)),
                       num_data_, kSampleSize, options_.confidence)));
    }
    // A small set has few distinct samples: draw each once and stop, rather
    // than repeat them up to max_iterations when none yields a model.
    const long long num_distinct = NumDistinctSamples(max_trials);
    const bool enumerate = num_distinct <= max_trials;
    if (enumerate) max_trials = static_cast<int>(num_distinct);
    const int trial_cap = max_trials;
    std::vector<int> sample(kSampleSize);
    std::vector<int> combination(kSampleSize);
    for (int i = 0; i < kSampleSize; ++i) combination[i] = i;
    std::vector<Model> models;
    int trial = 0;
    for (; trial < max_trials; ++trial) {
      if (enumerate) {
        for (int i = 0; i < kSampleSize; ++i) sample[i] = order_[combination[i]];
        NextCombination(&combination);
      } else {
        DrawSample(&sample);
      }
      models.clear();
      estimator_.MinimalSolve(sample, &models);
      bool improved = false;
      for (const Model& model : models) {
        const double score = Score(model, best_score);
        if (score < best_score) {
          best_score = score;
          best_model = model;
          improved = true;
          have_model = true;
        }
      }
      if (!improved) continue;
      if (options_.local_optimization) {
        LocalOptimize(&best_model, &best_score);
      }
      best_inliers = CountInliers(best_model);
      best_inlier_ratio_ = static_cast<double>(best_inliers) / num_data_;
      const int required = RansacRequiredIterations(
          best_inliers, num_data_, kSampleSize, options_.confidence);
      max_trials = std::min(trial_cap, std::max(options_.min_iterations, required));
    }
    result.num_iterations = trial;
    if (!have_model) return result;

    if (options_.final_refinement) {
      for (int round = 0; round < options_.max_refinements; ++round) {
        std::vector<int> inliers = Inliers(best_model);
        if (static_cast<int>(inliers.size()) < kSampleSize) break;
        Model refined = best_model;
        if (!estimator_.Refine(inliers, &refined)) break;
        const double score = Score(refined, best_score);
        if (!(score < best_score)) break;
        const bool converged = score > best_score * (1.0 - 1e-9);
        best_score = score;
        best_model = refined;
        if (converged) break;
      }
    }

    result.success = true;
    result.model = best_model;
    result.score = best_score;
    result.inlier_mask.assign(num_data_, 0);
    for (int i = 0; i < num_data_; ++i) {
      if (estimator_.SquaredError(best_model, i) <= threshold2_) {
        result.inlier_mask[i] = 1;
        ++result.num_inliers;
      }
    }
    return result;
  }

 private:
  // C(num_data, kSampleSize), or limit + 1 when that is larger.
  long long NumDistinctSamples(int limit) const {
    // C(n, k) = C(n, n - k), and C(n, i) grows with i up to n / 2.
    const int k = std::min(kSampleSize, num_data_ - kSampleSize);
    long long count = 1;
    for (int i = 0; i < k; ++i) {
      count = count * (num_data_ - i) / (i + 1);
      if (count > limit) return static_cast<long long>(limit) + 1;
    }
    return count;
  }

  // The next k-subset of 0..num_data-1 in lexicographic order.
  void NextCombination(std::vector<int>* combination) const {
    int i = kSampleSize - 1;
    while (i >= 0 && (*combination)[i] == num_data_ - kSampleSize + i) --i;
    if (i < 0) return;
    ++(*combination)[i];
    for (int j = i + 1; j < kSampleSize; ++j) (*combination)[j] = (*combination)[j - 1] + 1;
  }

  void DrawSample(std::vector<int>* sample) {
    std::uniform_int_distribution<int> pick(0, num_data_ - 1);
    for (int i = 0; i < kSampleSize; ++i) {
      int index;
      bool repeated;
      do {
        index = pick(rng_);
        repeated = false;
        for (int j = 0; j < i; ++j) repeated |= (*sample)[j] == index;
      } while (repeated);
      (*sample)[i] = index;
    }
  }

  // MSAC cost, or +inf once the model can no longer win: its cost exceeds
  // `bound`, or (a sequential test in the spirit of Matas and Chum's SPRT)
  // the data seen so far, in random order, hold fewer than half the inliers
  // that the best model's inlier ratio predicts. A model as good as the best
  // fails that test with negligible probability (< 1e-3 at the first check
  // for 16 expected inliers), while the many bad models of a RANSAC run are
  // dropped after a few dozen data instead of half the data.
  double Score(const Model& model, double bound) const {
    double score = 0;
    int inliers = 0;
    int next_check = 64;
    for (int k = 0; k < num_data_; ++k) {
      const double e2 = estimator_.SquaredError(model, order_[k]);
      if (e2 < threshold2_) {
        score += e2;
        ++inliers;
      } else {
        score += threshold2_;
      }
      if (score >= bound) return std::numeric_limits<double>::infinity();
      if (k + 1 == next_check) {
        next_check *= 2;
        const double expected = best_inlier_ratio_ * (k + 1);
        if (expected >= 16 && inliers < 0.5 * expected) {
          return std::numeric_limits<double>::infinity();
        }
      }
    }
    return score;
  }

  std::vector<int> Inliers(const Model& model) const {
    std::vector<int> inliers;
    for (int i = 0; i < num_data_; ++i) {
      if (estimator_.SquaredError(model, i) <= threshold2_) inliers.push_back(i);
    }
    return inliers;
  }

  int CountInliers(const Model& model) const {
    int count = 0;
    for (int i = 0; i < num_data_; ++i) {
      count += estimator_.SquaredError(model, i) <= threshold2_;
    }
    return count;
  }

  void LocalOptimize(Model* model, double* score) const {
    std::vector<Model> candidates;
    for (int round = 0; round < options_.lo_max_iterations; ++round) {
      const std::vector<int> inliers = Inliers(*model);
      if (static_cast<int>(inliers.size()) <= kSampleSize) return;
      candidates.clear();
      estimator_.NonMinimalSolve(inliers, *model, &candidates);
      bool improved = false;
      for (const Model& candidate : candidates) {
        const double candidate_score = Score(candidate, *score);
        if (candidate_score < *score) {
          *score = candidate_score;
          *model = candidate;
          improved = true;
        }
      }
      if (!improved) return;
    }
  }

  const Estimator& estimator_;
  const RansacOptions& options_;
  const int num_data_;
  const double threshold2_;
  std::mt19937 rng_;
  // A random order of the data for scoring (see Score()).
  std::vector<int> order_;
  double best_inlier_ratio_ = 0;
};

}  // namespace internal

// Runs RANSAC with the estimator. Throws std::invalid_argument for invalid
// options.
template <typename Estimator>
RansacResult<typename Estimator::Model> Ransac(const Estimator& estimator,
                                               const RansacOptions& options) {
  ThrowIfInvalid(RansacOptionsProblem(options));
  return internal::RansacRunner<Estimator>(estimator, options).Run();
}

}  // namespace flysfm
