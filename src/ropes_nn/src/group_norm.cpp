// group_norm: a fused kernel forward and backward, and — when a backward must itself be
// differentiable (grad(..., create_graph = true)) — the same gradient through the composed
// differentiable formula, so second derivatives stay exact.
#include <algorithm>
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

// how many sequential sums run interleaved (see group_norm)
constexpr std::int64_t kChains = 8;

// layout: x as [n, groups, channels_per_group, pixels]
struct Layout {
  std::int64_t n, c, groups, per_group, pixels;
  std::int64_t group_size() const { return per_group * pixels; }
};

class GroupNormNode final : public Node {
 public:
  // mask: for group_norm_relu, one byte per element of x, 1 where the normalised value is
  // positive (the ReLU's gradient), held in float storage from the pool; empty otherwise
  GroupNormNode(const Layout& l, float eps, Buffer mean, Buffer rstd, Buffer mask)
      : l_(l), eps_(eps), mean_(std::move(mean)), rstd_(std::move(rstd)), mask_(std::move(mask)) {}
  const char* name() const override { return mask_.empty() ? "group_norm" : "group_norm_relu"; }

  std::vector<Tensor> backward(const Tensor& gy) override {
    const Tensor& x = inputs[0];
    const Tensor& gamma = inputs[1];
    const Tensor& beta = inputs[2];
    if (grad_mode_enabled()) {
      // create_graph: differentiate the composed form, keeping the result differentiable
      Tensor y = composed_group_norm(x, static_cast<int>(l_.groups), gamma, beta, eps_);
      if (!mask_.empty())
        y = relu(y);
      return grad_stopping_at_inputs({y}, {x, gamma, beta}, {gy}, /*create_graph=*/true);
    }
    return fused_backward(gy);
  }

 private:
  // dx = rstd (dxhat - mean(dxhat) - xhat mean(dxhat xhat)) per group, dxhat = gy gamma;
  // dgamma = sum gy xhat, dbeta = sum gy over samples and pixels (per-block partial sums
  // added in block order, blocks fixed by the batch size)
  // With the ReLU, gy where the mask is 1 and 0 elsewhere takes gy's place (what relu's
  // backward gives group_norm's).
  std::vector<Tensor> fused_backward(const Tensor& gy) {
    const Tensor& x = inputs[0];
    const float* xp = x.data();
    const float* gp = gy.data();
    const std::uint8_t* mask = mask_bytes();
    const float* gamma = inputs[1].data();
    Buffer dx(static_cast<std::size_t>(x.numel()));
    const int blocks = reduction_blocks(l_.n);
    std::vector<std::vector<double>> dgamma(static_cast<std::size_t>(blocks),
                                            std::vector<double>(static_cast<std::size_t>(l_.c)));
    std::vector<std::vector<double>> dbeta = dgamma;
    for_each_reduction_block(l_.n, [&](int block, std::int64_t begin, std::int64_t end) {
      auto& dg = dgamma[static_cast<std::size_t>(block)];
      auto& db = dbeta[static_cast<std::size_t>(block)];
      // each channel's two sums over its pixels, kChains / 2 channels interleaved (each sum
      // in its own order: see group_norm), channel t of the block at s_gy[t], s_gy_xhat[t]
      const std::int64_t channels = (end - begin) * l_.c;
      std::vector<double> s_gy(static_cast<std::size_t>(channels)),
          s_gy_xhat(static_cast<std::size_t>(channels));
      constexpr std::int64_t kAtOnce = kChains / 2;
      for (std::int64_t first = 0; first < channels; first += kAtOnce) {
        const std::int64_t count = std::min(kAtOnce, channels - first);
        const float* xs[kAtOnce];
        const float* gs[kAtOnce];
        double mu[kAtOnce], rstd[kAtOnce], a[kAtOnce] = {}, b[kAtOnce] = {};
        for (std::int64_t j = 0; j < kAtOnce; ++j) {
          const std::int64_t t = first + std::min(j, count - 1);
          const std::int64_t i = begin + t / l_.c, ch = t % l_.c;
          const std::size_t stat = static_cast<std::size_t>(i * l_.groups + ch / l_.per_group);
          mu[j] = mean_[stat];
          rstd[j] = rstd_[stat];
          xs[j] = xp + (i * l_.c + ch) * l_.pixels;
          gs[j] = gp + (i * l_.c + ch) * l_.pixels;
        }
        if (mask == nullptr) {
          for (std::int64_t p = 0; p < l_.pixels; ++p)
            for (std::int64_t j = 0; j < kAtOnce; ++j) {
              const double xhat = (xs[j][p] - mu[j]) * rstd[j];
              a[j] += gs[j][p];
              b[j] += gs[j][p] * xhat;
            }
        } else {
          const std::uint8_t* ms[kAtOnce];
          for (std::int64_t j = 0; j < kAtOnce; ++j)
            ms[j] = mask + (gs[j] - gp);
          for (std::int64_t p = 0; p < l_.pixels; ++p)
            for (std::int64_t j = 0; j < kAtOnce; ++j) {
              const double xhat = (xs[j][p] - mu[j]) * rstd[j];
              const float g = ms[j][p] ? gs[j][p] : 0.0f;
              a[j] += g;
              b[j] += g * xhat;
            }
        }
        for (std::int64_t j = 0; j < count; ++j) {
          s_gy[static_cast<std::size_t>(first + j)] = a[j];
          s_gy_xhat[static_cast<std::size_t>(first + j)] = b[j];
        }
      }
      for (std::int64_t i = begin; i < end; ++i) {
        for (std::int64_t g = 0; g < l_.groups; ++g) {
          const std::size_t stat = static_cast<std::size_t>(i * l_.groups + g);
          const double mu = mean_[stat], rstd = rstd_[stat];
          const std::int64_t base = (i * l_.groups + g) * l_.group_size();
          double sum_dxhat = 0, sum_dxhat_xhat = 0;
          for (std::int64_t k = 0; k < l_.per_group; ++k) {
            const std::int64_t ch = g * l_.per_group + k;
            const std::size_t t = static_cast<std::size_t>((i - begin) * l_.c + ch);
            dg[static_cast<std::size_t>(ch)] += s_gy_xhat[t];
            db[static_cast<std::size_t>(ch)] += s_gy[t];
            sum_dxhat += gamma[ch] * s_gy[t];
            sum_dxhat_xhat += gamma[ch] * s_gy_xhat[t];
          }
          const double m = static_cast<double>(l_.group_size());
          const double a = sum_dxhat / m, b = sum_dxhat_xhat / m;
          for (std::int64_t k = 0; k < l_.per_group; ++k) {
            const std::int64_t ch = g * l_.per_group + k, row = base + k * l_.pixels;
            const float* xr = xp + row;
            const float* gr = gp + row;
            float* dr = dx.data() + row;
            // two loops without a branch inside, so that both vectorise
            if (mask == nullptr) {
              for (std::int64_t p = 0; p < l_.pixels; ++p) {
                const double xhat = (xr[p] - mu) * rstd;
                dr[p] = static_cast<float>(rstd * (gamma[ch] * gr[p] - a - xhat * b));
              }
            } else {
              const std::uint8_t* mr = mask + row;
              for (std::int64_t p = 0; p < l_.pixels; ++p) {
                const double xhat = (xr[p] - mu) * rstd;
                const float gv = mr[p] != 0 ? gr[p] : 0.0f;
                dr[p] = static_cast<float>(rstd * (gamma[ch] * gv - a - xhat * b));
              }
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

  const std::uint8_t* mask_bytes() const {
    return mask_.empty() ? nullptr : reinterpret_cast<const std::uint8_t*>(mask_.data());
  }

  Layout l_;
  float eps_;
  Buffer mean_, rstd_;  // per (sample, group); held as float, computed in double
  Buffer mask_;
};

// group_norm, and with `with_relu` group_norm_relu
Tensor normalize(const Tensor& x, int groups, const Tensor& gamma, const Tensor& beta, float eps,
                 bool with_relu) {
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
  const bool graph = needs_graph({x, gamma, beta});
  Buffer mask(with_relu && graph ? static_cast<std::size_t>((x.numel() + 3) / 4) : 0);
  std::uint8_t* mask_bytes = reinterpret_cast<std::uint8_t*>(mask.data());
  const float* xp = x.data();
  const float* gp = gamma.data();
  const float* bp = beta.data();
  // The sums over a group are sequential chains of double additions, each a few cycles long:
  // kChains groups' chains run interleaved, each in its own order (the same bits as one group
  // at a time, several times the throughput).
  parallel_for(n * groups, [&](int, std::int64_t begin, std::int64_t end) {
    const std::int64_t size = l.group_size();
    for (std::int64_t first = begin; first < end; first += kChains) {
      const std::int64_t chains = std::min<std::int64_t>(kChains, end - first);
      const float* v[kChains];
      for (std::int64_t j = 0; j < kChains; ++j)
        v[j] = xp + (first + std::min(j, chains - 1)) * size;
      double sum[kChains] = {}, mu[kChains], sq[kChains] = {};
      for (std::int64_t k = 0; k < size; ++k)
        for (std::int64_t j = 0; j < kChains; ++j)
          sum[j] += v[j][k];
      for (std::int64_t j = 0; j < kChains; ++j)
        mu[j] = sum[j] / static_cast<double>(size);
      for (std::int64_t k = 0; k < size; ++k)
        for (std::int64_t j = 0; j < kChains; ++j)
          sq[j] += (v[j][k] - mu[j]) * (v[j][k] - mu[j]);
      for (std::int64_t j = 0; j < chains; ++j) {
        const std::int64_t s = first + j;
        const double r = 1.0 / std::sqrt(sq[j] / static_cast<double>(size) + eps);
        mean[static_cast<std::size_t>(s)] = static_cast<float>(mu[j]);
        rstd[static_cast<std::size_t>(s)] = static_cast<float>(r);
        const std::int64_t g = s % groups;
        for (std::int64_t k = 0; k < l.per_group; ++k) {
          const std::int64_t ch = g * l.per_group + k;
          const double scale = r * gp[ch];
          const double shift = bp[ch] - mu[j] * scale;
          float* out = y.data() + s * size + k * l.pixels;
          const float* in = v[j] + k * l.pixels;
          for (std::int64_t p = 0; p < l.pixels; ++p)
            out[p] = static_cast<float>(in[p] * scale + shift);
          if (!with_relu)
            continue;
          // relu's forward, and where it passes the gradient
          for (std::int64_t p = 0; p < l.pixels; ++p)
            out[p] = out[p] > 0.0f ? out[p] : 0.0f;
          if (graph) {
            std::uint8_t* m = mask_bytes + (out - y.data());
            for (std::int64_t p = 0; p < l.pixels; ++p)
              m[p] = out[p] > 0.0f;
          }
        }
      }
    }
  });
  if (!graph)
    return Tensor(x.shape(), std::move(y));
  return make_op_result(
      x.shape(), std::move(y),
      std::make_shared<GroupNormNode>(l, eps, std::move(mean), std::move(rstd), std::move(mask)),
      {x, gamma, beta});
}

}  // namespace

Tensor group_norm(const Tensor& x, int groups, const Tensor& gamma, const Tensor& beta, float eps) {
  return normalize(x, groups, gamma, beta, eps, false);
}

Tensor group_norm_relu(const Tensor& x, int groups, const Tensor& gamma, const Tensor& beta,
                       float eps) {
  return normalize(x, groups, gamma, beta, eps, true);
}

}  // namespace ropes::nn
