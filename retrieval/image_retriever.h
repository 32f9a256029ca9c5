#pragma once

// Online retrieval for the engine: per new image, Describe it, Query the
// top-N already inserted images, then Insert it. Two modes:
//
// - Trained: a global descriptor extractor and a vocabulary tree given up
//   front (a RetrievalModel file from `flysfm train-retrieval`, or any
//   GlobalDescriptorExtractor such as a CNN, with a tree over its output).
//   Nothing is learnt during the session.
// - Bootstrapped (no model, the default): VLAD and the index are learnt from
//   the session's own images. The VLAD model is retrained when the image
//   count reaches 1, 2, 4, ... up to `bootstrap_freeze_images`, then frozen;
//   the index is exhaustive up to `min_tree_images`, then a vocabulary tree
//   trained on the inserted descriptors, rebuilt each time the count
//   doubles. Each retraining costs O(n), at counts growing geometrically, so
//   the cost per image is amortised O(1).

#include <functional>
#include <istream>
#include <memory>
#include <ostream>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "matching/features.h"
#include "retrieval/global_descriptor.h"
#include "retrieval/image_index.h"
#include "retrieval/retrieval_model.h"

namespace flysfm {

struct ImageRetrieverOptions {
  // Candidates per query (the paper's top-30).
  int num_candidates = 30;
  // false: an exhaustive index throughout (exact; for comparison).
  bool use_tree = true;
  VocabularyTreeIndexOptions tree_index;

  // Bootstrapped mode only. VLAD and tree settings for the session's own
  // training (the SIFT settings there are not used: features come in).
  RetrievalTrainingOptions training;
  // The VLAD model is frozen once trained on this many images; until then the
  // retriever keeps the images' features (about 1 MB each) to recompute
  // their descriptors after each retraining. 64 frames give the codebook
  // ~100 000 descriptors and PCA ~500 training vectors with crops.
  int bootstrap_freeze_images = 64;
  // Below this many images the index is exhaustive: exact, and as fast as
  // the tree at that size.
  int min_tree_images = 256;

  bool Check() const;
};

// A descriptor tagged with the model generation that made it: bootstrapped
// retraining changes the descriptor space, and a descriptor from an older
// generation must not be compared with the new one.
struct RetrievalDescriptor {
  Eigen::VectorXf vector;
  int generation = 0;
};

class ImageRetriever {
 public:
  // Bootstrapped mode. Bad options: std::invalid_argument.
  explicit ImageRetriever(const ImageRetrieverOptions& options);
  // Trained mode from a model file's content.
  ImageRetriever(const ImageRetrieverOptions& options, std::shared_ptr<const RetrievalModel> model);
  // Trained mode with any extractor and a tree over its descriptors (same
  // dimension, else std::invalid_argument).
  ImageRetriever(const ImageRetrieverOptions& options,
                 std::shared_ptr<const GlobalDescriptorExtractor> extractor,
                 std::shared_ptr<const VocabularyTree> tree);

  bool bootstrapped() const { return bootstrapped_; }

  // The global descriptor of a new image. Before the first insertion in
  // bootstrapped mode there is no model yet: the vector is empty, and a
  // query with it returns nothing (there is nothing to return).
  RetrievalDescriptor Describe(const cv::Mat& image, const FeatureSet& features) const;

  // The `n` inserted images most similar to the descriptor (fewer when fewer
  // are inserted), most similar first. A descriptor of an older generation:
  // std::invalid_argument.
  std::vector<RetrievalCandidate> Query(const RetrievalDescriptor& descriptor, int n) const;
  std::vector<RetrievalCandidate> Query(const RetrievalDescriptor& descriptor) const {
    return Query(descriptor, options_.num_candidates);
  }

  // Adds an image (new id). `descriptor` is Describe's result for it; a stale
  // one is recomputed from `features`. May retrain (bootstrapped mode), after
  // which earlier descriptors are stale.
  void Insert(image_t image_id, const cv::Mat& image, const FeatureSet& features,
              const RetrievalDescriptor& descriptor);

  // The `n` inserted images most similar to inserted image `image_id`,
  // itself excluded (e.g. the ripples of the local bundle adjustment).
  std::vector<RetrievalCandidate> QueryInserted(image_t image_id, int n) const;

  int NumImages() const { return index_ ? index_->Size() : 0; }
  int generation() const { return generation_; }
  // How often the VLAD model was (re)trained and the tree (re)built.
  int num_model_trainings() const { return num_model_trainings_; }
  int num_tree_builds() const { return num_tree_builds_; }
  bool uses_tree() const { return tree_ != nullptr; }

  // The engine's checkpoint. What a bootstrapped retriever learnt (VLAD
  // model, tree: megabytes, changed only at a retraining) is written apart
  // from the rest (schedule, index), and only when `model_version()`
  // changed; a trained retriever's model is read from its file again.
  // Read restores into a retriever made the same way (bootstrapped or
  // trained, nothing inserted yet): `model` is the learnt model of the
  // version the state names (nullptr when it names none), `features_of`
  // gives the features of the images a bootstrapped model still retains
  // for its next training. Throws std::runtime_error on a truncated or
  // inconsistent stream, or on a checkpoint made the other way.
  int model_version() const { return num_model_trainings_ + num_tree_builds_; }
  void WriteModel(std::ostream& out) const;
  void Write(std::ostream& out) const;
  void Read(std::istream& in, std::istream* model,
            const std::function<const FeatureSet&(image_t)>& features_of);

 private:
  void Retrain();
  void RebuildIndex(std::vector<image_t> ids, const std::vector<Eigen::VectorXf>& descriptors);

  ImageRetrieverOptions options_;
  bool bootstrapped_ = false;
  std::shared_ptr<const GlobalDescriptorExtractor> extractor_;
  std::shared_ptr<const VocabularyTree> tree_;
  std::unique_ptr<ImageIndex> index_;
  int generation_ = 0;

  // Bootstrapped mode: features kept until the model is frozen, with ids.
  std::vector<image_t> retained_ids_;
  std::vector<FeatureSet> retained_features_;
  bool frozen_ = false;
  int next_training_at_ = 1;
  int next_tree_at_ = 0;
  int num_model_trainings_ = 0;
  int num_tree_builds_ = 0;
};

}  // namespace flysfm
