#pragma once

// Images that could not register yet (the paper's Fig. 2 has every image
// either registered or waiting): each waits until its registered verified
// neighbourhood has grown since its last try, then is tried again. Nothing
// leaves the pool but by registering.

#include <functional>
#include <istream>
#include <ostream>
#include <vector>

#include "geometry/types.h"

namespace flysfm {

class PendingPool {
 public:
  // The number of registered verified neighbours an image has now.
  using NeighbourCount = std::function<int(image_t)>;

  void Add(image_t image_id) { waiting_.push_back({image_id, -1}); }
  void Remove(image_t image_id);
  // Records a try with the neighbourhood it saw.
  void MarkTried(image_t image_id, int num_registered_neighbours);
  // Every waiting image becomes due again (the end of a batch).
  void ForgetTries();

  // The first waiting image, in arrival order, whose neighbourhood is
  // non-empty and differs from its last try; kInvalidImageId when none.
  image_t NextDue(const NeighbourCount& count) const;

  std::vector<image_t> Images() const;

  // The engine's checkpoint; Read throws std::runtime_error on a truncated
  // stream.
  void Write(std::ostream& out) const;
  void Read(std::istream& in);
  bool empty() const { return waiting_.empty(); }

 private:
  struct Waiting {
    image_t image_id;
    int neighbours_at_last_try;
  };
  std::vector<Waiting> waiting_;
};

}  // namespace flysfm
