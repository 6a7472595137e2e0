#pragma once
// A tensor [n, ...] as an Eigen matrix [n, the rest flattened] (private to ropes_eval).
#include <ropes_nn/tensor.hpp>

#include <Eigen/Core>

#include <algorithm>
#include <cstdint>

namespace ropes::eval {

inline Eigen::MatrixXd to_matrix(const nn::Tensor& t) {
  const std::int64_t n = t.shape()[0], k = t.numel() / std::max<std::int64_t>(n, 1);
  Eigen::MatrixXd m(n, k);
  for (std::int64_t i = 0; i < n; ++i)
    for (std::int64_t j = 0; j < k; ++j)
      m(i, j) = t.data()[i * k + j];
  return m;
}

}  // namespace ropes::eval
