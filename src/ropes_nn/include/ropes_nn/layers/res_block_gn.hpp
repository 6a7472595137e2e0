#pragma once
/// @file layers/res_block_gn.hpp
/// ResBlockGN: the appendix's residual block, twice GroupNorm, ReLU and a 3x3 convolution.
#include "ropes_nn/layers/conv2d.hpp"
#include "ropes_nn/layers/group_norm.hpp"

#include <memory>

namespace ropes::nn {

/// The appendix's residual block: x + Conv(ReLU(GN(Conv(ReLU(GN(x)))))), 3x3 convolutions
/// keeping the channel count. Children: norm1, conv1, norm2, conv2.
class ResBlockGN : public Module {
 public:
  explicit ResBlockGN(std::int64_t channels, int groups = 0);

 protected:
  Tensor forward(const Tensor& x) override;

 private:
  std::shared_ptr<GroupNorm> norm1_, norm2_;
  std::shared_ptr<Conv2d> conv1_, conv2_;
};

}  // namespace ropes::nn
