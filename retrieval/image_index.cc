#include "retrieval/image_index.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

#include "geometry/check.h"

namespace flysfm {

ImageIndex::ImageIndex(int dim) : dim_(dim) {
  if (dim < 1) throw std::invalid_argument("image index dimension must be positive");
}

void ImageIndex::Insert(image_t image_id, const Eigen::VectorXf& descriptor) {
  if (descriptor.size() != dim_) {
    throw std::invalid_argument("descriptor of length " + std::to_string(descriptor.size()) +
                                " inserted into an index of dimension " + std::to_string(dim_));
  }
  if (!slots_.emplace(image_id, Size()).second) {
    throw std::invalid_argument("image " + std::to_string(image_id) + " already inserted");
  }
  ids_.push_back(image_id);
  data_.insert(data_.end(), descriptor.data(), descriptor.data() + dim_);
  OnInsert(Size() - 1);
}

Eigen::VectorXf ImageIndex::DescriptorOf(image_t image_id) const {
  const auto it = slots_.find(image_id);
  if (it == slots_.end()) {
    throw std::invalid_argument("image " + std::to_string(image_id) + " is not in the index");
  }
  return Eigen::Map<const Eigen::VectorXf>(SlotDescriptor(it->second), dim_);
}

void ImageIndex::CheckQuery(const Eigen::VectorXf& descriptor, int n) const {
  if (descriptor.size() != dim_ || n < 0) {
    throw std::invalid_argument("query of length " + std::to_string(descriptor.size()) +
                                " for " + std::to_string(n) + " images on an index of dimension " +
                                std::to_string(dim_));
  }
}

std::vector<RetrievalCandidate> ImageIndex::RankSlots(const Eigen::VectorXf& descriptor,
                                                      const std::vector<int>& slots,
                                                      int n) const {
  std::vector<RetrievalCandidate> ranked(slots.size());
  for (std::size_t k = 0; k < slots.size(); ++k) {
    const float d2 =
        (Eigen::Map<const Eigen::VectorXf>(SlotDescriptor(slots[k]), dim_) - descriptor)
            .squaredNorm();
    ranked[k] = {ids_[slots[k]], d2};
  }
  const auto closer = [](const RetrievalCandidate& a, const RetrievalCandidate& b) {
    return a.distance < b.distance || (a.distance == b.distance && a.image_id < b.image_id);
  };
  const std::size_t keep = std::min<std::size_t>(n, ranked.size());
  std::partial_sort(ranked.begin(), ranked.begin() + keep, ranked.end(), closer);
  ranked.resize(keep);
  for (RetrievalCandidate& c : ranked) c.distance = std::sqrt(c.distance);
  return ranked;
}

std::vector<RetrievalCandidate> ExhaustiveIndex::Query(const Eigen::VectorXf& descriptor,
                                                       int n) const {
  CheckQuery(descriptor, n);
  std::vector<int> all(Size());
  for (int k = 0; k < Size(); ++k) all[k] = k;
  return RankSlots(descriptor, all, n);
}

VocabularyTreeIndex::VocabularyTreeIndex(std::shared_ptr<const VocabularyTree> tree,
                                         const VocabularyTreeIndexOptions& options)
    : ImageIndex(tree ? tree->Dim() : 0), tree_(std::move(tree)), options_(options) {
  if (!options_.Check()) throw std::invalid_argument("invalid VocabularyTreeIndexOptions");
  leaf_slots_.resize(tree_->NumLeaves());
}

void VocabularyTreeIndex::OnInsert(int slot) {
  leaf_slots_[tree_->FindLeaf(SlotDescriptor(slot))].push_back(slot);
}

std::vector<RetrievalCandidate> VocabularyTreeIndex::Query(const Eigen::VectorXf& descriptor,
                                                           int n) const {
  CheckQuery(descriptor, n);
  const std::size_t wanted = std::min<std::size_t>(
      Size(), std::max<std::size_t>(options_.min_candidates,
                                    std::size_t(std::ceil(options_.candidate_factor * n))));
  std::vector<int> candidates;
  if (n > 0 && wanted > 0) {
    tree_->VisitLeavesBestFirst(descriptor.data(), [&](int leaf) {
      const std::vector<int>& slots = leaf_slots_[leaf];
      candidates.insert(candidates.end(), slots.begin(), slots.end());
      return candidates.size() < wanted;
    });
  }
  return RankSlots(descriptor, candidates, n);
}

}  // namespace flysfm
