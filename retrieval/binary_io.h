#pragma once

// Matrices in the versioned binary model files (geometry/binary_io.h has the
// rest).

#include <istream>
#include <ostream>

#include "geometry/binary_io.h"
#include "retrieval/types.h"

namespace flysfm {

void WriteMatrix(std::ostream& out, const RowMatrixXf& matrix);
// Rejects sizes over `max_elements` before allocating, so a corrupt size
// field cannot exhaust memory.
RowMatrixXf ReadMatrix(std::istream& in, const char* what,
                       std::int64_t max_elements = std::int64_t(1) << 28);

}  // namespace flysfm
