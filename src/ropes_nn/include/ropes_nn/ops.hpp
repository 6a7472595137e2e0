#pragma once
/// @file ops.hpp
/// Differentiable operations on Tensors. Each records an autodiff node when grad mode is on
/// and an input requires grad; each node's backward is written with these same operations,
/// so gradients can be differentiated again.
///
/// Binary elementwise operations broadcast as numpy does: shapes are aligned at the right,
/// and a dimension of 1 stretches to the other's. Mismatches throw std::invalid_argument
/// printing the operation and both shapes.

#include <cstdint>
#include <vector>

#include "ropes_nn/tensor.hpp"

namespace ropes::nn {

// --- elementwise, broadcasting ---------------------------------------------------------------
Tensor add(const Tensor& a, const Tensor& b);
Tensor sub(const Tensor& a, const Tensor& b);
Tensor mul(const Tensor& a, const Tensor& b);
/// a / b; no check for b == 0 (IEEE results, as PyTorch).
Tensor div(const Tensor& a, const Tensor& b);

/// The shape `a` and `b` broadcast to; std::invalid_argument naming `op` when they don't.
Shape broadcast_shape(const Shape& a, const Shape& b, const char* op);

// --- with a constant --------------------------------------------------------------------------
Tensor add_scalar(const Tensor& x, float c);
Tensor mul_scalar(const Tensor& x, float c);

// --- elementwise, unary ------------------------------------------------------------------------
Tensor neg(const Tensor& x);
Tensor exp(const Tensor& x);
/// Natural log; log of a value <= 0 gives -inf or NaN as in IEEE arithmetic.
Tensor log(const Tensor& x);
/// log(1 + x), accurate for small x.
Tensor log1p(const Tensor& x);
Tensor sqrt(const Tensor& x);
Tensor square(const Tensor& x);
/// |x|; its derivative is sign(x), taken as 0 at 0 (as PyTorch).
Tensor abs(const Tensor& x);
/// max(x, 0); derivative 1 where x > 0, else 0.
Tensor relu(const Tensor& x);
/// 1 / (1 + exp(-x)), computed without overflow for large |x|.
Tensor sigmoid(const Tensor& x);

// --- shape --------------------------------------------------------------------------------------
/// Same values in a new shape with the same number of elements (shares storage).
Tensor reshape(const Tensor& x, const Shape& shape);
/// [N, ...] -> [N, prod(...)].
Tensor flatten(const Tensor& x);
/// Repeats `x` along broadcast dimensions to `shape`.
Tensor broadcast_to(const Tensor& x, const Shape& shape);
/// Sums `x` over the dimensions that broadcasting to x.shape() would have stretched from
/// `shape`: the adjoint of broadcast_to.
Tensor sum_to(const Tensor& x, const Shape& shape);
/// Concatenation along `axis` (all other dimensions equal).
Tensor concat(const std::vector<Tensor>& xs, int axis);
/// Elements [begin, end) along `axis`.
Tensor slice(const Tensor& x, int axis, std::int64_t begin, std::int64_t end);
/// The transpose of a rank-2 tensor.
Tensor transpose(const Tensor& x);

// --- reductions ---------------------------------------------------------------------------------
/// Sum over every element: a scalar.
Tensor sum(const Tensor& x);
/// Sum over `axes` (negative axes count from the end); `keepdim` keeps them as size 1.
Tensor sum(const Tensor& x, const std::vector<int>& axes, bool keepdim = false);
Tensor mean(const Tensor& x);
Tensor mean(const Tensor& x, const std::vector<int>& axes, bool keepdim = false);

// --- linear algebra -----------------------------------------------------------------------------
/// [m, k] x [k, n] -> [m, n].
Tensor matmul(const Tensor& a, const Tensor& b);

// --- convolution -------------------------------------------------------------------------------
/// How a convolution pads its input, as Flax/JAX define the names:
///   same():  output size ceil(input / stride); the total padding
///            max((out - 1) * stride + kernel - input, 0) is split with the smaller half
///            before (top/left) and the larger after (bottom/right).
///   valid(): no padding; output size floor((input - kernel) / stride) + 1.
///   explicit_pads(top, bottom, left, right).
struct Padding2d {
  enum class Mode { kSame, kValid, kExplicit };
  Mode mode = Mode::kSame;
  int top = 0, bottom = 0, left = 0, right = 0;  // kExplicit only
  static Padding2d same() { return {Mode::kSame}; }
  static Padding2d valid() { return {Mode::kValid}; }
  static Padding2d explicit_pads(int top, int bottom, int left, int right) {
    return {Mode::kExplicit, top, bottom, left, right};
  }
};

/// 2-D cross-correlation (what deep-learning libraries call convolution).
/// x: [N, C, H, W], w: [O, C, KH, KW] (PyTorch's layout) -> [N, O, OH, OW].
/// No bias: add one with add(y, reshape(b, {1, O, 1, 1})). Throws std::invalid_argument for
/// mismatched channels, a stride < 1, negative padding, or an empty output.
Tensor conv2d(const Tensor& x, const Tensor& w, int stride = 1,
              const Padding2d& padding = Padding2d::same());
/// conv2d then add(y, reshape(b, {1, O, 1, 1})), b: [O]: the same values and graph. Where no
/// graph is recorded (inference) the bias is where each output starts its sum, which saves
/// a pass over y and gives the same bits.
Tensor conv2d(const Tensor& x, const Tensor& w, const Tensor& b, int stride = 1,
              const Padding2d& padding = Padding2d::same());

/// The transpose (adjoint) of conv2d with the same kernel, stride and padding: what a
/// decoder uses to upsample. x: [N, Cin, H, W], w: [Cin, Cout, KH, KW] (PyTorch's
/// ConvTranspose2d layout) -> [N, Cout, OH, OW].
/// With Padding2d::same() the output is [H * stride, W * stride] and the padding is the
/// one conv2d SAME would use from that size back to H (kernel 4, stride 2: one pixel each
/// side, i.e. PyTorch's ConvTranspose2d(k=4, s=2, padding=1)). With valid() or explicit
/// pads the output is (H - 1) * stride + KH - top - bottom (PyTorch's formula).
Tensor conv_transpose2d(const Tensor& x, const Tensor& w, int stride = 1,
                        const Padding2d& padding = Padding2d::same());

// --- normalisation
// --------------------------------------------------------------------------------
/// Group normalisation of x [N, C, H, W] (or [N, C]) over `groups` groups of C / groups
/// channels: (x - mean) / sqrt(var + eps) per sample and group, then gamma * . + beta per
/// channel (gamma, beta: [C]). var is the biased variance. eps defaults to Flax's 1e-6
/// (PyTorch's GroupNorm uses 1e-5). Built from differentiable operations.
Tensor group_norm(const Tensor& x, int groups, const Tensor& gamma, const Tensor& beta,
                  float eps = 1e-6f);
/// relu(group_norm(x, ...)) in one pass, forward and backward: the same values and gradients
/// (of every order), without the normalised tensor in between; the graph keeps one byte per
/// element for the ReLU's gradient.
Tensor group_norm_relu(const Tensor& x, int groups, const Tensor& gamma, const Tensor& beta,
                       float eps = 1e-6f);

// --- benchmarks ----------------------------------------------------------------------------------
/// Floating-point operations done by the matrix products (matmul and the convolution
/// kernels) since the last reset, all threads together: for benchmarks' GFLOP/s.
std::uint64_t flop_count();
void reset_flop_count();

// --- losses -------------------------------------------------------------------------------------
/// mean((prediction - target)^2) over all elements.
Tensor mse_loss(const Tensor& prediction, const Tensor& target);
/// mean(max(z, 0) - z * y + log(1 + exp(-|z|))): binary cross-entropy of logits z against
/// targets y in [0, 1], stable for any z (as PyTorch's BCEWithLogitsLoss).
Tensor bce_with_logits(const Tensor& logits, const Tensor& targets);
/// The same loss per element, not averaged (same shape as the logits): the per-sample
/// statistic of a mean loss over micro-batches (train_step.hpp).
Tensor bce_with_logits_elementwise(const Tensor& logits, const Tensor& targets);

}  // namespace ropes::nn
