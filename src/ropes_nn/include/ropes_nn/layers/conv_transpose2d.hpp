#pragma once
/// @file layers/conv_transpose2d.hpp
/// ConvTranspose2d: a 2-D transposed convolution with a bias per output channel.
#include "ropes_nn/module.hpp"
#include "ropes_nn/ops.hpp"

namespace ropes::nn {

/// y = conv_transpose2d(x, weight, stride, padding) + bias.  [N, in, H, W] -> [N, out, OH, OW]
/// (with SAME: OH = H * stride).
class ConvTranspose2d : public Module {
 public:
  ConvTranspose2d(std::int64_t in_channels, std::int64_t out_channels, std::int64_t kernel,
                  int stride = 1, Padding2d padding = Padding2d::same(), bool bias = true);

 protected:
  Tensor forward(const Tensor& x) override;

 private:
  int stride_;
  Padding2d padding_;
  Tensor weight_, bias_;
};

}  // namespace ropes::nn
