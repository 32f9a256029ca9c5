#pragma once

// A trained retrieval model: the VLAD extractor (codebook + PCA-whitening)
// and the vocabulary tree over its descriptors, in one versioned file. Made
// by `flysfm train-retrieval` (trained mode) or by ImageRetriever from the
// session's own images (bootstrapped mode).

#include <string>
#include <vector>

#include "matching/features.h"
#include "retrieval/vlad.h"
#include "retrieval/vocabulary_tree.h"

namespace flysfm {

struct RetrievalTrainingOptions {
  // Extraction settings for training images; use the same at run time.
  SiftOptions sift;
  VladOptions vlad;
  VocabularyTreeOptions tree;

  bool Check() const { return sift.Check() && vlad.Check() && tree.Check(); }
};

struct RetrievalModel {
  VladExtractor vlad;
  // Trained on the VLAD descriptors of the training images and their crops.
  VocabularyTree tree;

  // Versioned binary file ("FSRMODEL" tag); Load throws std::runtime_error on
  // a missing, truncated or corrupt file, Save when it cannot write.
  void Save(const std::string& path) const;
  static RetrievalModel Load(const std::string& path);
};

// Trains VLAD, then the tree on the training descriptors. Needs at least one
// image with features; bad options: std::invalid_argument.
RetrievalModel TrainRetrievalModel(const std::vector<const FeatureSet*>& images,
                                   const RetrievalTrainingOptions& options);

struct RetrievalTrainingReport {
  int num_images = 0;    // used for training
  int num_features = 0;  // extracted over them
  // Files that could not be decoded, with the reason.
  std::vector<std::string> skipped;
};

// What `flysfm train-retrieval` runs: decode and extract every image file
// (ListImageFiles order), skipping undecodable ones, then TrainRetrievalModel.
// No usable image: std::invalid_argument.
RetrievalModel TrainRetrievalModelFromFiles(const std::vector<std::string>& image_paths,
                                            const RetrievalTrainingOptions& options,
                                            RetrievalTrainingReport* report = nullptr);

}  // namespace flysfm
