// group_norm: a fused kernel forward and backward, and — when a backward must itself be
// differentiable (grad(..., create_graph = true)) — the same gradient through the composed
// differentiable formula, so second derivatives stay exact.
#include <cmath>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "ropes_nn/ops.hpp"
#include "ropes_nn/parallel.hpp"
#include "tensor_impl.hpp"

namespace ropes::nn {

namespace {

[[noreturn]] void fail(const std::string& what) {
  throw std::invalid_argument("group_norm: " + what);
}

Shape channel_shape(const Tensor& x) {
  std::vector<std::int64_t> dims(static_cast<std::size_t>(x.rank()), 1);
  dims[1] = x.shape()[1];
  return Shape(dims);
}

// the composed form: every step a differentiable operation
Tensor composed_group_norm(const Tensor& x, int groups, const Tensor& gamma, const Tensor& beta,
                           float eps) {
  const std::int64_t n = x.shape()[0];
  const Tensor grouped = reshape(x, Shape{n, groups, x.numel() / (n * groups)});
  const Tensor centred = sub(grouped, mean(grouped, {2}, true));
  const Tensor var = mean(square(centred), {2}, true);
  const Tensor normed = reshape(div(centred, sqrt(add_scalar(var, eps))), x.shape());
  const Shape channel = channel_shape(x);
  return add(mul(normed, reshape(gamma, channel)), reshape(beta, channel));
}

// layout: x as [n, groups, channels_per_group, pixels]
struct Layout {
  std::int64_t n, c, groups, per_group, pixels;
  std::int64_t group_size() const { return per_group * pixels; }
};

class GroupNormNode final : public Node {
 public:
  GroupNormNode(const Layout& l, float eps, Buffer mean, Buffer rstd)
      : l_(l), eps_(eps), mean_(std::move(mean)), rstd_(std::move(rstd)) {}
  const char* name() const override { return "group_norm"; }

  std::vector<Tensor> backward(const Tensor& gy) override {
    const Tensor& x = inputs[0];
    const Tensor& gamma = inputs[1];
    const Tensor& beta = inputs[2];
    if (grad_mode_enabled()) {
      // create_graph: differentiate the composed form, keeping the result differentiable
      const Tensor y = composed_group_norm(x, static_cast<int>(l_.groups), gamma, beta, eps_);
      return grad_stopping_at_inputs({y}, {x, gamma, beta}, {gy}, /*create_graph=*/true);
    }
    return fused_backward(gy);
  }

 private:
  // dx = rstd (dxhat - mean(dxhat) - xhat mean(dxhat xhat)) per group, dxhat = gy gamma;
  // dgamma = sum gy xhat, dbeta = sum gy over samples and pixels (per-block partial sums
  // added in block order, blocks fixed by the batch size)
  std::vector<Tensor> fused_backward(const Tensor& gy) {
    const Tensor& x = inputs[0];
    const float* xp = x.data();
    const float* gp = gy.data();
    const float* gamma = inputs[1].data();
    Buffer dx(static_cast<std::size_t>(x.numel()));
    const int blocks = reduction_blocks(l_.n);
    std::vector<std::vector<double>> dgamma(static_cast<std::size_t>(blocks),
                                            std::vector<double>(static_cast<std::size_t>(l_.c)));
    std::vector<std::vector<double>> dbeta = dgamma;
    for_each_reduction_block(l_.n, [&](int block, std::int64_t begin, std::int64_t end) {
      auto& dg = dgamma[static_cast<std::size_t>(block)];
      auto& db = dbeta[static_cast<std::size_t>(block)];
      for (std::int64_t i = begin; i < end; ++i) {
        for (std::int64_t g = 0; g < l_.groups; ++g) {
          const std::size_t stat = static_cast<std::size_t>(i * l_.groups + g);
          const double mu = mean_[stat], rstd = rstd_[stat];
          const std::int64_t base = (i * l_.groups + g) * l_.group_size();
          double sum_dxhat = 0, sum_dxhat_xhat = 0;
          for (std::int64_t k = 0; k < l_.per_group; ++k) {
            const std::int64_t ch = g * l_.per_group + k;
            double s_gy = 0, s_gy_xhat = 0;
            for (std::int64_t p = 0; p < l_.pixels; ++p) {
              const std::int64_t at = base + k * l_.pixels + p;
              const double xhat = (xp[at] - mu) * rstd;
              s_gy += gp[at];
              s_gy_xhat += gp[at] * xhat;
            }
            dg[static_cast<std::size_t>(ch)] += s_gy_xhat;
            db[static_cast<std::size_t>(ch)] += s_gy;
            sum_dxhat += gamma[ch] * s_gy;
            sum_dxhat_xhat += gamma[ch] * s_gy_xhat;
          }
          const double m = static_cast<double>(l_.group_size());
          const double a = sum_dxhat / m, b = sum_dxhat_xhat / m;
          for (std::int64_t k = 0; k < l_.per_group; ++k) {
            const std::int64_t ch = g * l_.per_group + k;
            for (std::int64_t p = 0; p < l_.pixels; ++p) {
              const std::int64_t at = base + k * l_.pixels + p;
              const double xhat = (xp[at] - mu) * rstd;
              dx[static_cast<std::size_t>(at)] =
                  static_cast<float>(rstd * (gamma[ch] * gp[at] - a - xhat * b));
            }
          }
        }
      }
    });
    Buffer dgamma_total(static_cast<std::size_t>(l_.c)),
        dbeta_total(static_cast<std::size_t>(l_.c));
    for (std::int64_t ch = 0; ch < l_.c; ++ch) {
      double sg = 0, sb = 0;
      for (int c = 0; c < blocks; ++c) {
        sg += dgamma[static_cast<std::size_t>(c)][static_cast<std::size_t>(ch)];
        sb += dbeta[static_cast<std::size_t>(c)][static_cast<std::size_t>(ch)];
      }
      dgamma_total[static_cast<std::size_t>(ch)] = static_cast<float>(sg);
      dbeta_total[static_cast<std::size_t>(ch)] = static_cast<float>(sb);
    }
    return {Tensor(x.shape(), std::move(dx)), Tensor(Shape{l_.c}, std::move(dgamma_total)),
            Tensor(Shape{l_.c}, std::move(dbeta_total))};
  }

  Layout l_;
  float eps_;
  Buffer mean_, rstd_;  // per (sample, group); held as float, computed in double
};

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
  const Layout l{n, c, groups, c / groups, n * c == 0 ? 0 : x.numel() / (n * c)};
  if (x.numel() == 0)
    fail("x " + x.shape().str() + " is empty");

  // statistics per (sample, group) in double, then the normalised, affine output
  Buffer mean(static_cast<std::size_t>(n * groups));
  Buffer rstd(mean.size());
  Buffer y(static_cast<std::size_t>(x.numel()));
  const float* xp = x.data();
  const float* gp = gamma.data();
  const float* bp = beta.data();
  parallel_for(n * groups, [&](int, std::int64_t begin, std::int64_t end) {
    for (std::int64_t s = begin; s < end; ++s) {
      const float* v = xp + s * l.group_size();
      double sum = 0;
      for (std::int64_t k = 0; k < l.group_size(); ++k)
        sum += v[k];
      const double mu = sum / static_cast<double>(l.group_size());
      double sq = 0;
      for (std::int64_t k = 0; k < l.group_size(); ++k)
        sq += (v[k] - mu) * (v[k] - mu);
      const double r = 1.0 / std::sqrt(sq / static_cast<double>(l.group_size()) + eps);
      mean[static_cast<std::size_t>(s)] = static_cast<float>(mu);
      rstd[static_cast<std::size_t>(s)] = static_cast<float>(r);
      const std::int64_t g = s % groups;
      for (std::int64_t k = 0; k < l.per_group; ++k) {
        const std::int64_t ch = g * l.per_group + k;
        const double scale = r * gp[ch];
        const double shift = bp[ch] - mu * scale;
        float* out = y.data() + s * l.group_size() + k * l.pixels;
        const float* in = v + k * l.pixels;
        for (std::int64_t p = 0; p < l.pixels; ++p)
          out[p] = static_cast<float>(in[p] * scale + shift);
      }
    }
  });
  if (!needs_graph({x, gamma, beta}))
    return Tensor(x.shape(), std::move(y));
  return make_op_result(x.shape(), std::move(y),
                        std::make_shared<GroupNormNode>(l, eps, std::move(mean), std::move(rstd)),
                        {x, gamma, beta});
}

}  // namespace ropes::nn
