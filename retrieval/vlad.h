#pragma once

// VLAD over RootSIFT (Jegou et al. 2010; Arandjelovic & Zisserman 2013):
// residuals of the local descriptors to their nearest codebook word, summed
// per word, intra-normalised, power-normalised, L2-normalised, then
// PCA-whitened to a few hundred dimensions and L2-normalised again. Trained
// unsupervised from a set of images.

#include <cstdint>
#include <istream>
#include <ostream>
#include <vector>

#include "retrieval/global_descriptor.h"
#include "retrieval/pca_whitening.h"
#include "retrieval/types.h"

namespace flysfm {

struct VladOptions {
  // Codebook size. 64 words x 128 = 8 192 raw dimensions: the usual VLAD
  // size, still cheap to assign (2 000 x 64 dot products per image).
  int num_words = 64;
  // Output dimension after PCA-whitening (fewer when trained on fewer than
  // pca_dim + 1 samples).
  int pca_dim = 256;
  // Signed power normalisation x -> sign(x) |x|^power (0.5: signed square
  // root), damps bursty words.
  double power = 0.5;
  // Whitening regulariser (PcaWhitening::Train): 1 halves the weight of
  // low-variance directions relative to full whitening, which on a few
  // thousand training samples mostly amplifies noise.
  double whitening_regularisation = 1.0;
  // PCA is learnt only from at least this many training vectors (whole images
  // plus crops); with fewer, Compute returns the raw VLAD.
  int min_pca_samples = 256;
  // Random descriptors (over all training images) the codebook is learnt on.
  int max_training_descriptors = 50000;
  int kmeans_iterations = 15;
  // Each training image also gives the VLAD of this many random crops (40-70
  // % of each side), so a few dozen images give enough samples for PCA and
  // the tree, and the samples cover partial overlaps.
  int crops_per_image = 8;
  // Crops with fewer keypoints than this are not used.
  int min_crop_features = 50;
  std::uint32_t seed = 0;

  bool Check() const;
};

class VladExtractor : public GlobalDescriptorExtractor {
 public:
  // Learns the codebook and the PCA-whitening from the features of
  // `images` (at least one image with features). `training_descriptors`
  // (optional) receives the final descriptors of the training vectors (whole
  // images and crops), one per row, e.g. to train a vocabulary tree on. Bad
  // options or no features: std::invalid_argument.
  static VladExtractor Train(const std::vector<const FeatureSet*>& images,
                             const VladOptions& options,
                             RowMatrixXf* training_descriptors = nullptr);

  int Dim() const override;
  // The image is not used and may be empty.
  Eigen::VectorXf Compute(const cv::Mat& image, const FeatureSet& features) const override;
  Eigen::VectorXf Compute(const FeatureSet& features) const;
  // The normalised VLAD before PCA (NumWords() * 128 values); zero for an
  // image without features.
  Eigen::VectorXf ComputeRaw(const FeatureSet& features) const;

  int NumWords() const { return int(codebook_.rows()); }
  bool HasPca() const { return !pca_.empty(); }
  const RowMatrixXf& codebook() const { return codebook_; }

  void Write(std::ostream& out) const;
  static VladExtractor Read(std::istream& in);

  bool operator==(const VladExtractor& other) const {
    return IdenticalMatrices(codebook_, other.codebook_) && power_ == other.power_ &&
           pca_ == other.pca_;
  }

 private:
  std::vector<int> AssignWords(const FeatureDescriptors& descriptors) const;
  // Over the descriptors listed in `subset`, or all when it is null.
  Eigen::VectorXf Aggregate(const FeatureDescriptors& descriptors,
                            const std::vector<int>& words,
                            const std::vector<int>* subset) const;

  RowMatrixXf codebook_;
  float power_ = 0.5f;
  PcaWhitening pca_;
};

}  // namespace flysfm
