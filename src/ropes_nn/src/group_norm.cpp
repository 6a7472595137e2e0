// group_norm, composed of differentiable operations (so its second derivatives come free)
#include <stdexcept>
#include <string>

#include "ropes_nn/ops.hpp"

namespace ropes::nn {

namespace {
[[noreturn]] void fail(const std::string& what) {
  throw std::invalid_argument("group_norm: " + what);
}
}  // namespace

Tensor group_norm(const Tensor& x, int groups, const Tensor& gamma, const Tensor& beta, float eps) {
  if (!x.defined() || !gamma.defined() || !beta.defined())
    fail("undefined input");
  if (x.rank() < 2)
    fail("x " + x.shape().str() + "; expected [N, C, ...]");
  const std::int64_t n = x.shape()[0], c = x.shape()[1];
  if (groups < 1 || c % groups != 0) {
    fail(std::to_string(groups) + " groups for " + std::to_string(c) +
         " channels; expected a divisor of the channel count");
  }
  if (gamma.shape() != Shape{c} || beta.shape() != Shape{c}) {
    fail("gamma " + gamma.shape().str() + " and beta " + beta.shape().str() + "; expected [" +
         std::to_string(c) + "] each");
  }
  // statistics per (sample, group) over the group's channels and pixels
  const Tensor grouped = reshape(x, Shape{n, groups, x.numel() / (n * groups)});
  const Tensor centred = sub(grouped, mean(grouped, {2}, true));
  const Tensor var = mean(square(centred), {2}, true);
  const Tensor normed = reshape(div(centred, sqrt(add_scalar(var, eps))), x.shape());
  // per-channel affine
  std::vector<std::int64_t> channel_dims(static_cast<std::size_t>(x.rank()), 1);
  channel_dims[1] = c;
  const Shape channel(channel_dims);
  return add(mul(normed, reshape(gamma, channel)), reshape(beta, channel));
}

}  // namespace ropes::nn
