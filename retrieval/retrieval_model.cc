#include "retrieval/retrieval_model.h"

#include <fstream>
#include <stdexcept>

#include "matching/image_decode.h"
#include "retrieval/binary_io.h"

namespace flysfm {
namespace {

constexpr char kModelMagic[9] = "FSRMODEL";
constexpr std::uint32_t kModelVersion = 1;

}  // namespace

void RetrievalModel::Save(const std::string& path) const {
  std::ofstream out(path, std::ios::binary);
  if (!out) throw std::runtime_error("cannot write retrieval model '" + path + "'");
  WriteHeader(out, kModelMagic, kModelVersion);
  vlad.Write(out);
  tree.Write(out);
  if (!out) throw std::runtime_error("error writing retrieval model '" + path + "'");
}

RetrievalModel RetrievalModel::Load(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw std::runtime_error("cannot open retrieval model '" + path + "'");
  try {
    ReadHeader(in, kModelMagic, kModelVersion);
    RetrievalModel model;
    model.vlad = VladExtractor::Read(in);
    model.tree = VocabularyTree::Read(in);
    if (model.tree.Dim() != model.vlad.Dim()) {
      throw std::runtime_error("tree and descriptor dimensions differ");
    }
    return model;
  } catch (const std::runtime_error& e) {
    throw std::runtime_error("retrieval model '" + path + "': " + e.what());
  }
}

RetrievalModel TrainRetrievalModel(const std::vector<const FeatureSet*>& images,
                                   const RetrievalTrainingOptions& options) {
  if (!options.Check()) throw std::invalid_argument("invalid RetrievalTrainingOptions");
  RetrievalModel model;
  RowMatrixXf training_descriptors;
  model.vlad = VladExtractor::Train(images, options.vlad, &training_descriptors);
  model.tree = VocabularyTree::Train(training_descriptors, options.tree);
  return model;
}

RetrievalModel TrainRetrievalModelFromFiles(const std::vector<std::string>& image_paths,
                                            const RetrievalTrainingOptions& options,
                                            RetrievalTrainingReport* report) {
  if (!options.Check()) throw std::invalid_argument("invalid RetrievalTrainingOptions");
  RetrievalTrainingReport local;
  std::vector<FeatureSet> features;
  for (const std::string& path : image_paths) {
    const DecodedImage decoded = DecodeImageFile(path, {}, options.sift.max_image_size);
    if (!decoded.ok()) {
      local.skipped.push_back(decoded.error);
      continue;
    }
    features.push_back(ExtractFeatures(decoded.image, decoded.grey, options.sift));
    local.num_features += features.back().size();
  }
  std::vector<const FeatureSet*> pointers;
  for (const FeatureSet& f : features) {
    if (f.size() > 0) pointers.push_back(&f);
  }
  local.num_images = int(pointers.size());
  if (report) *report = local;
  if (pointers.empty()) {
    throw std::invalid_argument("no training image with features among " +
                                std::to_string(image_paths.size()) + " files");
  }
  return TrainRetrievalModel(pointers, options);
}

}  // namespace flysfm
