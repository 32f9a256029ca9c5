#include "core/pending_pool.h"

#include <algorithm>

#include "geometry/binary_io.h"

namespace flysfm {

void PendingPool::Remove(image_t image_id) {
  waiting_.erase(std::remove_if(waiting_.begin(), waiting_.end(),
                                [&](const Waiting& w) { return w.image_id == image_id; }),
                 waiting_.end());
}

void PendingPool::MarkTried(image_t image_id, int num_registered_neighbours) {
  for (Waiting& waiting : waiting_) {
    if (waiting.image_id == image_id) waiting.neighbours_at_last_try = num_registered_neighbours;
  }
}

void PendingPool::ForgetTries() {
  for (Waiting& waiting : waiting_) waiting.neighbours_at_last_try = -1;
}

image_t PendingPool::NextDue(const NeighbourCount& count) const {
  for (const Waiting& waiting : waiting_) {
    const int neighbours = count(waiting.image_id);
    if (neighbours > 0 && neighbours != waiting.neighbours_at_last_try) return waiting.image_id;
  }
  return kInvalidImageId;
}

std::vector<image_t> PendingPool::Images() const {
  std::vector<image_t> ids;
  ids.reserve(waiting_.size());
  for (const Waiting& waiting : waiting_) ids.push_back(waiting.image_id);
  return ids;
}

void PendingPool::Write(std::ostream& out) const { WriteVector(out, waiting_); }

void PendingPool::Read(std::istream& in) {
  waiting_ = ReadVector<Waiting>(in, "waiting images", std::size_t(1) << 24);
}

}  // namespace flysfm
