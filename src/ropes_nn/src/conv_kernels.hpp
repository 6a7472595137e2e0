#pragma once
// Private: the three kernels of conv.cpp, for its tests. Each image's im2col matrix is built
// a tile of output pixels at a time, a tile being a block of the product's columns (or of its
// sum over pixels) as gemm.hpp blocks it, so that the tile stays in cache and each element
// gets the bits the whole-image product gives; kWholeImages builds it whole (the reference the
// tests compare the tiles with, and what products too small for the blocked kernel take).
#include <cstdint>

#include "ropes_nn/buffer.hpp"
#include "ropes_nn/tensor.hpp"

namespace ropes::nn {

// shapes and padding of one forward convolution x [n, c, h, w] * w [o, c, kh, kw]
struct ConvGeometry {
  std::int64_t n, c, h, w, o, kh, kw, oh, ow;
  int stride;
  int top, left;  // bottom/right padding only shows in oh, ow

  std::int64_t patch() const { return c * kh * kw; }  // rows of the im2col matrix
  std::int64_t pixels() const { return oh * ow; }     // its columns
  Shape x_shape() const { return Shape{n, c, h, w}; }
  Shape w_shape() const { return Shape{o, c, kh, kw}; }
  Shape y_shape() const { return Shape{n, o, oh, ow}; }
};

enum class ConvTiling { kTiles, kWholeImages };

// y = conv(x, w) [n, o, oh, ow], plus bias[o] on channel o where bias is given (the same
// bits as adding it to the product after)
Buffer conv_forward(const float* x, const float* w, const ConvGeometry& g,
                    ConvTiling tiling = ConvTiling::kTiles, const float* bias = nullptr);
// dx [n, c, h, w] from gy [n, o, oh, ow]: the adjoint in x (conv_transpose2d's forward)
Buffer conv_input_grad(const float* gy, const float* w, const ConvGeometry& g,
                       ConvTiling tiling = ConvTiling::kTiles);
// dw [o, c, kh, kw] from x and gy: the adjoint in w
Buffer conv_weight_grad(const float* x, const float* gy, const ConvGeometry& g,
                        ConvTiling tiling = ConvTiling::kTiles);

}  // namespace ropes::nn
