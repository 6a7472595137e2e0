#pragma once
/// @file ops.hpp
/// Differentiable operations on Tensors. Each records an autodiff node when grad mode is on
/// and an input requires grad; each node's backward is written with these same operations,
/// so gradients can be differentiated again.
///
/// Binary elementwise operations broadcast as numpy does: shapes are aligned at the right,
/// and a dimension of 1 stretches to the other's. Mismatches throw std::invalid_argument
/// printing the operation and both shapes.

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

// --- losses -------------------------------------------------------------------------------------
/// mean((prediction - target)^2) over all elements.
Tensor mse_loss(const Tensor& prediction, const Tensor& target);
/// mean(max(z, 0) - z * y + log(1 + exp(-|z|))): binary cross-entropy of logits z against
/// targets y in [0, 1], stable for any z (as PyTorch's BCEWithLogitsLoss).
Tensor bce_with_logits(const Tensor& logits, const Tensor& targets);

}  // namespace ropes::nn
