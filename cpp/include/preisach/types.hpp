// Common array types of the preisach C++ core (pure C++, no Python).
#pragma once

#include <Eigen/Core>

namespace preisach {

using RowMatrixXd = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
using MatrixRef = Eigen::Ref<const RowMatrixXd>;
using VectorRef = Eigen::Ref<const Eigen::VectorXd>;

}  // namespace preisach
