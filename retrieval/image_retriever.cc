#include "retrieval/image_retriever.h"

#include <algorithm>
#include <stdexcept>
#include <string>

#include "geometry/check.h"
#include "retrieval/binary_io.h"

namespace flysfm {

bool ImageRetrieverOptions::Check() const {
  return num_candidates >= 1 && tree_index.Check() && training.vlad.Check() &&
         training.tree.Check() && bootstrap_freeze_images >= 1 && min_tree_images >= 1;
}

ImageRetriever::ImageRetriever(const ImageRetrieverOptions& options)
    : options_(options), bootstrapped_(true) {
  if (!options_.Check()) throw std::invalid_argument("invalid ImageRetrieverOptions");
  next_tree_at_ = options_.min_tree_images;
}

ImageRetriever::ImageRetriever(const ImageRetrieverOptions& options,
                               std::shared_ptr<const RetrievalModel> model)
    : ImageRetriever(options,
                     std::shared_ptr<const GlobalDescriptorExtractor>(model, &model->vlad),
                     std::shared_ptr<const VocabularyTree>(model, &model->tree)) {}

ImageRetriever::ImageRetriever(const ImageRetrieverOptions& options,
                               std::shared_ptr<const GlobalDescriptorExtractor> extractor,
                               std::shared_ptr<const VocabularyTree> tree)
    : options_(options), extractor_(std::move(extractor)) {
  if (!options_.Check()) throw std::invalid_argument("invalid ImageRetrieverOptions");
  if (!extractor_ || !tree || tree->Dim() != extractor_->Dim()) {
    throw std::invalid_argument("retrieval model: missing parts or dimensions differ");
  }
  if (options_.use_tree) {
    tree_ = std::move(tree);
    index_ = std::make_unique<VocabularyTreeIndex>(tree_, options_.tree_index);
  } else {
    index_ = std::make_unique<ExhaustiveIndex>(extractor_->Dim());
  }
}

RetrievalDescriptor ImageRetriever::Describe(const cv::Mat& image,
                                             const FeatureSet& features) const {
  RetrievalDescriptor descriptor;
  descriptor.generation = generation_;
  if (extractor_) descriptor.vector = extractor_->Compute(image, features);
  return descriptor;
}

std::vector<RetrievalCandidate> ImageRetriever::Query(const RetrievalDescriptor& descriptor,
                                                      int n) const {
  if (descriptor.generation != generation_) {
    throw std::invalid_argument("retrieval descriptor of generation " +
                                std::to_string(descriptor.generation) +
                                " is stale (model generation " + std::to_string(generation_) +
                                "): describe the image again");
  }
  if (!index_ || index_->Size() == 0) return {};
  return index_->Query(descriptor.vector, n);
}

std::vector<RetrievalCandidate> ImageRetriever::QueryInserted(image_t image_id, int n) const {
  if (!index_ || !index_->Contains(image_id)) {
    throw std::invalid_argument("image " + std::to_string(image_id) + " was not inserted");
  }
  std::vector<RetrievalCandidate> result = index_->Query(index_->DescriptorOf(image_id), n + 1);
  result.erase(std::remove_if(result.begin(), result.end(),
                              [&](const RetrievalCandidate& c) { return c.image_id == image_id; }),
               result.end());
  if (int(result.size()) > n) result.resize(n);
  return result;
}

void ImageRetriever::Insert(image_t image_id, const cv::Mat& image, const FeatureSet& features,
                            const RetrievalDescriptor& descriptor) {
  if (index_ && index_->Contains(image_id)) {
    throw std::invalid_argument("image " + std::to_string(image_id) + " already inserted");
  }
  if (bootstrapped_ && !frozen_) {
    retained_ids_.push_back(image_id);
    retained_features_.push_back(features);
    if (int(retained_ids_.size()) >= next_training_at_) {
      Retrain();
      return;
    }
  }
  const Eigen::VectorXf vector = descriptor.generation == generation_ && descriptor.vector.size() > 0
                                     ? descriptor.vector
                                     : extractor_->Compute(image, features);
  index_->Insert(image_id, vector);
  if (bootstrapped_ && options_.use_tree && index_->Size() >= next_tree_at_) {
    std::vector<Eigen::VectorXf> descriptors;
    for (const image_t id : index_->ImageIds()) descriptors.push_back(index_->DescriptorOf(id));
    RebuildIndex(index_->ImageIds(), descriptors);
  }
}

void ImageRetriever::Retrain() {
  std::vector<const FeatureSet*> images;
  for (const FeatureSet& f : retained_features_) images.push_back(&f);
  const bool any_features = std::any_of(images.begin(), images.end(),
                                        [](const FeatureSet* f) { return f->size() > 0; });
  const int n = int(retained_ids_.size());
  next_training_at_ = 2 * n;
  if (!any_features) {
    // Only textureless frames so far: nothing to learn from. They stay
    // retained and are indexed by the first training that has features.
    FLYSFM_CHECK(!extractor_ && !index_);
    return;
  }
  extractor_ = std::make_shared<VladExtractor>(VladExtractor::Train(images, options_.training.vlad));
  ++num_model_trainings_;
  ++generation_;
  std::vector<Eigen::VectorXf> descriptors;
  for (const FeatureSet& f : retained_features_) descriptors.push_back(extractor_->Compute(cv::Mat(), f));
  if (n >= options_.bootstrap_freeze_images) {
    frozen_ = true;
    retained_features_.clear();
    retained_features_.shrink_to_fit();
  }
  RebuildIndex(retained_ids_, descriptors);
  if (frozen_) retained_ids_.clear();
}

void ImageRetriever::RebuildIndex(std::vector<image_t> ids,
                                  const std::vector<Eigen::VectorXf>& descriptors) {
  FLYSFM_CHECK(ids.size() == descriptors.size() && !descriptors.empty());
  const int n = int(ids.size());
  const int dim = int(descriptors.front().size());
  if (options_.use_tree && n >= options_.min_tree_images) {
    RowMatrixXf points(n, dim);
    for (int k = 0; k < n; ++k) points.row(k) = descriptors[k].transpose();
    tree_ = std::make_shared<const VocabularyTree>(
        VocabularyTree::Train(points, options_.training.tree));
    index_ = std::make_unique<VocabularyTreeIndex>(tree_, options_.tree_index);
    ++num_tree_builds_;
    next_tree_at_ = 2 * n;
  } else {
    tree_.reset();
    index_ = std::make_unique<ExhaustiveIndex>(dim);
  }
  for (int k = 0; k < n; ++k) index_->Insert(ids[k], descriptors[k]);
}

void ImageRetriever::WriteModel(std::ostream& out) const {
  const auto* vlad = dynamic_cast<const VladExtractor*>(extractor_.get());
  WriteValue(out, std::uint8_t(bootstrapped_ && vlad != nullptr));
  if (bootstrapped_ && vlad) vlad->Write(out);
  WriteValue(out, std::uint8_t(bootstrapped_ && tree_ != nullptr));
  if (bootstrapped_ && tree_) tree_->Write(out);
}

void ImageRetriever::Write(std::ostream& out) const {
  WriteValue(out, std::uint8_t(bootstrapped_));
  for (const int value : {generation_, int(frozen_), next_training_at_, next_tree_at_,
                          num_model_trainings_, num_tree_builds_}) {
    WriteValue(out, value);
  }
  WriteVector(out, retained_ids_);
  WriteValue(out, std::uint8_t(index_ != nullptr));
  if (!index_) return;
  RowMatrixXf descriptors(index_->Size(), index_->Dim());
  for (int slot = 0; slot < index_->Size(); ++slot) {
    descriptors.row(slot) = index_->DescriptorOf(index_->ImageIds()[slot]).transpose();
  }
  WriteVector(out, index_->ImageIds());
  WriteMatrix(out, descriptors);
}

void ImageRetriever::Read(std::istream& in, std::istream* model,
                          const std::function<const FeatureSet&(image_t)>& features_of) {
  FLYSFM_CHECK(!index_ || index_->Size() == 0);
  const bool bootstrapped = ReadValue<std::uint8_t>(in, "retrieval mode") != 0;
  if (bootstrapped != bootstrapped_) {
    throw std::runtime_error(bootstrapped
                                 ? "the checkpoint's retrieval learnt from the session's "
                                   "images: resume without a retrieval model"
                                 : "the checkpoint's retrieval used a trained model: resume "
                                   "with the same --retrieval-model");
  }
  generation_ = ReadValue<int>(in, "retrieval generation");
  frozen_ = ReadValue<int>(in, "retrieval state") != 0;
  next_training_at_ = ReadValue<int>(in, "retrieval state");
  next_tree_at_ = ReadValue<int>(in, "retrieval state");
  num_model_trainings_ = ReadValue<int>(in, "retrieval state");
  num_tree_builds_ = ReadValue<int>(in, "retrieval state");
  retained_ids_ = ReadVector<image_t>(in, "retained images", std::size_t(1) << 24);
  retained_features_.clear();
  if (!frozen_) {
    for (const image_t image_id : retained_ids_) retained_features_.push_back(features_of(image_id));
  }
  if (bootstrapped_) {
    extractor_.reset();
    tree_.reset();
    if (model_version() > 0) {
      if (!model) throw std::runtime_error("the checkpoint's retrieval model is missing");
      if (ReadValue<std::uint8_t>(*model, "retrieval model")) {
        extractor_ = std::make_shared<VladExtractor>(VladExtractor::Read(*model));
      }
      if (ReadValue<std::uint8_t>(*model, "retrieval tree")) {
        tree_ = std::make_shared<const VocabularyTree>(VocabularyTree::Read(*model));
      }
    }
  }
  index_.reset();
  if (!ReadValue<std::uint8_t>(in, "retrieval index")) {
    // Only a bootstrapped retriever that has not learnt yet has no index.
    if (!bootstrapped_ || extractor_) throw std::runtime_error("checkpoint without its index");
    return;
  }
  const std::vector<image_t> ids = ReadVector<image_t>(in, "indexed images", std::size_t(1) << 24);
  const RowMatrixXf descriptors = ReadMatrix(in, "global descriptors");
  if (descriptors.rows() != std::int64_t(ids.size()) || descriptors.cols() == 0 || !extractor_ ||
      descriptors.cols() != extractor_->Dim() || (tree_ && tree_->Dim() != extractor_->Dim())) {
    throw std::runtime_error("corrupt retrieval index in the checkpoint");
  }
  if (tree_) {
    index_ = std::make_unique<VocabularyTreeIndex>(tree_, options_.tree_index);
  } else {
    index_ = std::make_unique<ExhaustiveIndex>(int(descriptors.cols()));
  }
  for (std::size_t slot = 0; slot < ids.size(); ++slot) {
    index_->Insert(ids[slot], descriptors.row(slot).transpose());
  }
}

}  // namespace flysfm
