#include "ropes_nn/layers/dense.hpp"

#include <stdexcept>
#include <string>

#include "layer_checks.hpp"

namespace ropes::nn {

Dense::Dense(std::int64_t in_features, std::int64_t out_features, bool bias) {
  layer_checks::require_positive("Dense", "in_features", in_features);
  layer_checks::require_positive("Dense", "out_features", out_features);
  weight_ =
      register_parameter("weight", Shape{in_features, out_features}, "lecun_normal", in_features);
  if (bias)
    bias_ = register_parameter("bias", Shape{out_features}, "zeros");
}

Tensor Dense::forward(const Tensor& x) {
  if (x.rank() != 2 || x.shape()[1] != weight_.shape()[0]) {
    throw std::invalid_argument("Dense: input " + x.shape().str() + "; expected [N, " +
                                std::to_string(weight_.shape()[0]) + "]");
  }
  const Tensor y = matmul(x, weight_);
  return bias_.defined() ? add(y, bias_) : y;
}

}  // namespace ropes::nn
