#pragma once

#include <Eigen/Core>

namespace flysfm {

using Matrix3x4d = Eigen::Matrix<double, 3, 4>;
using Vector6d = Eigen::Matrix<double, 6, 1>;

}  // namespace flysfm
