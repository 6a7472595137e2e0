#pragma once
/// @file layers/dense.hpp
/// Dense: a fully connected layer.
#include "ropes_nn/module.hpp"
#include "ropes_nn/ops.hpp"

namespace ropes::nn {

/// y = x weight + bias.  [N, in] -> [N, out]
class Dense : public Module {
 public:
  Dense(std::int64_t in_features, std::int64_t out_features, bool bias = true);

 protected:
  Tensor forward(const Tensor& x) override;

 private:
  Tensor weight_, bias_;
};

}  // namespace ropes::nn
