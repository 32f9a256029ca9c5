#include "retrieval/vlad.h"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <random>
#include <stdexcept>

#include "geometry/check.h"
#include "retrieval/binary_io.h"
#include "retrieval/kmeans.h"

namespace flysfm {
namespace {

constexpr char kVladMagic[9] = "FSVLAD01";
constexpr std::uint32_t kVladVersion = 1;

void L2NormaliseInPlace(Eigen::VectorXf* v) {
  const float norm = v->norm();
  if (norm > 0.f) *v /= norm;
}

RowMatrixXf SampleDescriptors(const std::vector<const FeatureSet*>& images, int max_count,
                              std::mt19937& rng) {
  std::int64_t total = 0;
  for (const FeatureSet* f : images) total += f->descriptors.rows();
  const double fraction = std::min(1.0, double(max_count) / double(std::max<std::int64_t>(total, 1)));
  std::vector<std::pair<int, int>> picks;  // (image, row)
  for (int i = 0; i < int(images.size()); ++i) {
    const int rows = int(images[i]->descriptors.rows());
    std::vector<int> order(rows);
    std::iota(order.begin(), order.end(), 0);
    std::shuffle(order.begin(), order.end(), rng);
    const int take = std::min(rows, int(std::ceil(fraction * rows)));
    for (int k = 0; k < take; ++k) picks.emplace_back(i, order[k]);
  }
  RowMatrixXf sample(picks.size(), 128);
  for (std::size_t k = 0; k < picks.size(); ++k) {
    FeatureDescriptors row = images[picks[k].first]->descriptors.row(picks[k].second).cast<float>();
    RootSiftInPlace(&row);
    sample.row(k) = row;
  }
  return sample;
}

}  // namespace

bool VladOptions::Check() const {
  return num_words >= 1 && pca_dim >= 1 && power > 0 && power <= 1 &&
         whitening_regularisation >= 0 && min_pca_samples >= 2 &&
         max_training_descriptors >= num_words && kmeans_iterations >= 1 &&
         crops_per_image >= 0 && min_crop_features >= 1;
}

VladExtractor VladExtractor::Train(const std::vector<const FeatureSet*>& images,
                                   const VladOptions& options,
                                   RowMatrixXf* training_descriptors) {
  if (!options.Check()) throw std::invalid_argument("invalid VladOptions");
  std::vector<const FeatureSet*> usable;
  for (const FeatureSet* f : images) {
    if (f != nullptr && f->descriptors.rows() > 0) usable.push_back(f);
  }
  if (usable.empty()) {
    throw std::invalid_argument("VLAD training needs at least one image with features");
  }
  std::mt19937 rng(options.seed);
  VladExtractor vlad;
  vlad.power_ = float(options.power);
  KMeansOptions kmeans;
  kmeans.num_iterations = options.kmeans_iterations;
  kmeans.seed = options.seed;
  vlad.codebook_ = KMeans(SampleDescriptors(usable, options.max_training_descriptors, rng),
                          options.num_words, kmeans);

  // Training vectors: each image whole and a few random crops of it.
  std::vector<Eigen::VectorXf> samples;
  std::uniform_real_distribution<double> side(0.4, 0.7), unit(0.0, 1.0);
  for (const FeatureSet* f : usable) {
    const FeatureDescriptors root = RootSift(f->descriptors);
    const std::vector<int> words = vlad.AssignWords(root);
    samples.push_back(vlad.Aggregate(root, words, nullptr));
    for (int c = 0; c < options.crops_per_image; ++c) {
      const double w = side(rng) * f->width, h = side(rng) * f->height;
      const double x0 = unit(rng) * (f->width - w), y0 = unit(rng) * (f->height - h);
      std::vector<int> subset;
      for (int k = 0; k < f->size(); ++k) {
        const Keypoint& kp = f->keypoints[k];
        if (kp.x >= x0 && kp.x < x0 + w && kp.y >= y0 && kp.y < y0 + h) subset.push_back(k);
      }
      if (int(subset.size()) < options.min_crop_features) continue;
      samples.push_back(vlad.Aggregate(root, words, &subset));
    }
  }
  RowMatrixXf matrix(samples.size(), samples.front().size());
  for (std::size_t k = 0; k < samples.size(); ++k) matrix.row(k) = samples[k].transpose();
  if (int(samples.size()) >= options.min_pca_samples) {
    vlad.pca_ = PcaWhitening::Train(matrix, options.pca_dim, options.whitening_regularisation);
  }
  if (training_descriptors) {
    if (vlad.HasPca()) {
      training_descriptors->resize(matrix.rows(), vlad.Dim());
      for (Eigen::Index k = 0; k < matrix.rows(); ++k) {
        Eigen::VectorXf v = vlad.pca_.Apply(matrix.row(k).transpose());
        L2NormaliseInPlace(&v);
        training_descriptors->row(k) = v.transpose();
      }
    } else {
      *training_descriptors = std::move(matrix);
    }
  }
  return vlad;
}

int VladExtractor::Dim() const {
  return HasPca() ? pca_.OutputDim() : int(codebook_.rows() * codebook_.cols());
}

std::vector<int> VladExtractor::AssignWords(const FeatureDescriptors& descriptors) const {
  if (descriptors.rows() == 0) return {};
  return AssignToNearest(RowMatrixXf(descriptors), codebook_);
}

Eigen::VectorXf VladExtractor::Aggregate(const FeatureDescriptors& descriptors,
                                         const std::vector<int>& words,
                                         const std::vector<int>* subset) const {
  const int dim = int(codebook_.cols());
  RowMatrixXf residuals = RowMatrixXf::Zero(codebook_.rows(), dim);
  const auto add = [&](int k) {
    residuals.row(words[k]) += descriptors.row(k) - codebook_.row(words[k]);
  };
  if (subset) {
    for (int k : *subset) add(k);
  } else {
    for (int k = 0; k < int(words.size()); ++k) add(k);
  }
  for (Eigen::Index w = 0; w < residuals.rows(); ++w) {
    const float norm = residuals.row(w).norm();
    if (norm > 0.f) residuals.row(w) /= norm;
  }
  Eigen::VectorXf v = Eigen::Map<const Eigen::VectorXf>(residuals.data(), residuals.size());
  if (power_ != 1.f) {
    for (Eigen::Index i = 0; i < v.size(); ++i) {
      v[i] = std::copysign(std::pow(std::abs(v[i]), power_), v[i]);
    }
  }
  L2NormaliseInPlace(&v);
  return v;
}

Eigen::VectorXf VladExtractor::ComputeRaw(const FeatureSet& features) const {
  FLYSFM_CHECK(codebook_.rows() > 0);
  const FeatureDescriptors root = RootSift(features.descriptors);
  return Aggregate(root, AssignWords(root), nullptr);
}

Eigen::VectorXf VladExtractor::Compute(const FeatureSet& features) const {
  Eigen::VectorXf v = ComputeRaw(features);
  if (HasPca()) {
    v = pca_.Apply(v);
    L2NormaliseInPlace(&v);
  }
  return v;
}

Eigen::VectorXf VladExtractor::Compute(const cv::Mat& /*image*/,
                                       const FeatureSet& features) const {
  return Compute(features);
}

void VladExtractor::Write(std::ostream& out) const {
  WriteHeader(out, kVladMagic, kVladVersion);
  WriteValue(out, power_);
  WriteMatrix(out, codebook_);
  pca_.Write(out);
}

VladExtractor VladExtractor::Read(std::istream& in) {
  ReadHeader(in, kVladMagic, kVladVersion);
  VladExtractor vlad;
  vlad.power_ = ReadValue<float>(in, "VLAD power");
  vlad.codebook_ = ReadMatrix(in, "VLAD codebook");
  vlad.pca_ = PcaWhitening::Read(in);
  if (!(vlad.power_ > 0.f && vlad.power_ <= 1.f) || vlad.codebook_.rows() < 1 ||
      vlad.codebook_.cols() != 128 ||
      (vlad.HasPca() && vlad.pca_.InputDim() != vlad.codebook_.size())) {
    throw std::runtime_error("corrupt model file: inconsistent VLAD sizes");
  }
  return vlad;
}

}  // namespace flysfm
