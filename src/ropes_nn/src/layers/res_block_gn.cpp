#include "ropes_nn/layers/res_block_gn.hpp"

#include <memory>

namespace ropes::nn {

ResBlockGN::ResBlockGN(std::int64_t channels, int groups) {
  norm1_ = register_module("norm1", std::make_shared<GroupNorm>(channels, groups));
  conv1_ = register_module("conv1", std::make_shared<Conv2d>(channels, channels, 3));
  norm2_ = register_module("norm2", std::make_shared<GroupNorm>(channels, groups));
  conv2_ = register_module("conv2", std::make_shared<Conv2d>(channels, channels, 3));
}

Tensor ResBlockGN::forward(const Tensor& x) {
  const Tensor h = (*conv1_)(norm1_->with_relu(x));
  return add(x, (*conv2_)(norm2_->with_relu(h)));
}

}  // namespace ropes::nn
