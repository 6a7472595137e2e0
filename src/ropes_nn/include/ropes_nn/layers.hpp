#pragma once
/// @file layers.hpp
/// The layers of the ROPES networks (paper appendix, tables "Autoencoder1", "Autoencoder 2",
/// "LDR"): Conv2d, ConvTranspose2d, GroupNorm, Dense and ResBlockGN. Kernels are
/// initialised LeCun-normal (truncated normal, as Flax's default), biases to zero.
/// Shapes: images NCHW; Conv2d weight [O, C, KH, KW], ConvTranspose2d weight
/// [Cin, Cout, KH, KW] (PyTorch's layouts), Dense weight [in, out].

#include "ropes_nn/module.hpp"
#include "ropes_nn/ops.hpp"

namespace ropes::nn {

/// y = conv2d(x, weight, stride, padding) + bias.  [N, in, H, W] -> [N, out, OH, OW]
class Conv2d : public Module {
 public:
  Conv2d(std::int64_t in_channels, std::int64_t out_channels, std::int64_t kernel, int stride = 1,
         Padding2d padding = Padding2d::same(), bool bias = true);

 protected:
  Tensor forward(const Tensor& x) override;

 private:
  int stride_;
  Padding2d padding_;
  Tensor weight_, bias_;
};

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

/// group_norm with learned per-channel scale (gamma, "scale") and shift (beta, "bias").
/// `groups` defaults to min(32, channels), which must divide channels.
class GroupNorm : public Module {
 public:
  explicit GroupNorm(std::int64_t channels, int groups = 0, float eps = 1e-6f);
  int groups() const { return groups_; }

 protected:
  Tensor forward(const Tensor& x) override;

 private:
  int groups_;
  float eps_;
  Tensor scale_, bias_;
};

/// y = x weight + bias.  [N, in] -> [N, out]
class Dense : public Module {
 public:
  Dense(std::int64_t in_features, std::int64_t out_features, bool bias = true);

 protected:
  Tensor forward(const Tensor& x) override;

 private:
  Tensor weight_, bias_;
};

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
