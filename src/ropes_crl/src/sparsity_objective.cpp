#include "ropes_crl/sparsity_objective.hpp"

#include <ropes_nn/ops.hpp>

#include <stdexcept>

namespace ropes::crl {

using nn::Shape;

Tensor latent_score_differences(Ae2& ae2, const Tensor& y, const Tensor& v, bool create_graph) {
  if (y.shape() != v.shape())
    throw std::invalid_argument("latent_score_differences: codes " + y.shape().str() +
                                " and score differences " + v.shape().str() +
                                " must have the same shape");
  const Tensor z = ae2.encode(y);
  const Tensor y_hat = ae2.decode(z);
  return nn::grad({y_hat}, {z}, {v}, create_graph)[0];
}

Tensor unit_length_rows(const Tensor& v) {
  const std::int64_t n = v.shape()[0];
  const std::int64_t per = v.numel() / std::max<std::int64_t>(n, 1);
  std::vector<float> out(v.data(), v.data() + v.numel());
  for (std::int64_t i = 0; i < n; ++i) {
    double s = 0;
    for (std::int64_t j = 0; j < per; ++j)
      s += static_cast<double>(out[i * per + j]) * out[i * per + j];
    const double scale = s > 0 ? 1.0 / std::sqrt(s) : 0.0;
    for (std::int64_t j = 0; j < per; ++j)
      out[i * per + j] = static_cast<float>(out[i * per + j] * scale);
  }
  return Tensor(v.shape(), out);
}

Tensor mean_unit_length_rows(const Tensor& v) {
  const std::int64_t n = v.shape()[0];
  const std::int64_t per = v.numel() / std::max<std::int64_t>(n, 1);
  double length = 0;
  for (std::int64_t i = 0; i < n; ++i) {
    double s = 0;
    for (std::int64_t j = 0; j < per; ++j)
      s += static_cast<double>(v.data()[i * per + j]) * v.data()[i * per + j];
    length += std::sqrt(s);
  }
  length /= static_cast<double>(std::max<std::int64_t>(n, 1));
  const double scale = length > 0 ? 1.0 / length : 1.0;
  std::vector<float> out(v.data(), v.data() + v.numel());
  for (float& x : out)
    x = static_cast<float>(x * scale);
  return Tensor(v.shape(), out);
}

Tensor sparsity_penalty(const Tensor& mean_abs, std::int64_t target, SparsityNorm norm,
                        const Tensor& signed_mean) {
  const std::int64_t d = mean_abs.numel();
  if (target < 0 || target >= d)
    throw std::invalid_argument("sparsity_penalty: target latent " + std::to_string(target) +
                                " is outside [0, " + std::to_string(d) + ")");
  std::vector<float> e(static_cast<std::size_t>(d), 0.0f);
  e[static_cast<std::size_t>(target)] = 1.0f;
  Tensor row = nn::reshape(mean_abs, Shape{d});
  if (signed_mean.defined()) {
    if (signed_mean.numel() != d)
      throw std::invalid_argument("sparsity_penalty: signed mean has " +
                                  std::to_string(signed_mean.numel()) + " entries, expected " +
                                  std::to_string(d));
    std::vector<float> off(e.size());
    for (std::size_t i = 0; i < e.size(); ++i)
      off[i] = 1.0f - e[i];
    row = nn::add(nn::mul(row, Tensor(Shape{d}, off)),
                  nn::mul(nn::abs(nn::reshape(signed_mean, Shape{d})), Tensor(Shape{d}, e)));
  }
  const Tensor diff = nn::sub(row, Tensor(Shape{d}, e));
  return norm == SparsityNorm::kL1 ? nn::sum(nn::abs(diff)) : nn::sum(nn::square(diff));
}

namespace {

// rows [p * n / parts, (p + 1) * n / parts) of a set of n
Tensor part_of(const Tensor& t, std::size_t p, std::size_t parts) {
  const std::int64_t n = t.shape()[0];
  const std::int64_t b = n * static_cast<std::int64_t>(p) / static_cast<std::int64_t>(parts);
  const std::int64_t e = n * static_cast<std::int64_t>(p + 1) / static_cast<std::int64_t>(parts);
  if (e == b)
    return Tensor();
  return nn::slice(t, 0, b, e);
}

// the non-empty pieces, concatenated along dim 0
Tensor join(const std::vector<Tensor>& pieces) {
  std::vector<Tensor> kept;
  for (const Tensor& t : pieces)
    if (t.defined() && t.shape()[0] > 0)
      kept.push_back(t);
  return kept.size() == 1 ? kept[0] : nn::concat(kept, 0);
}

}  // namespace

Tensor logit_correlation_loss(const Tensor& m) {
  if (m.shape() != Shape{5})
    throw std::invalid_argument("logit_correlation_loss: moments " + m.shape().str() +
                                "; expected [5]: E z, E z^2, E z l, E l, E l^2");
  const auto at = [&m](std::int64_t i) { return nn::slice(m, 0, i, i + 1); };
  const Tensor ez = at(0), el = at(3);
  const Tensor cov = nn::sub(at(2), nn::mul(ez, el));
  const Tensor var_z = nn::sub(at(1), nn::square(ez)), var_l = nn::sub(at(4), nn::square(el));
  const Tensor corr =
      nn::div(cov, nn::sqrt(nn::add_scalar(nn::relu(nn::mul(var_z, var_l)), 1e-12f)));
  return nn::sum(nn::neg(nn::add_scalar(corr, -1.0f)));
}

nn::BatchLoss ae2_batch_loss(Ae2& ae2, const Ae2Batch& batch, double lambda, SparsityNorm norm,
                             std::int64_t micro_batch, std::size_t* micro_batches,
                             SparsityDiagonal diagonal) {
  const std::size_t terms = lambda > 0 ? batch.term_codes.size() : 0;
  const std::size_t logit_terms = batch.logit_weight > 0 ? batch.term_logits.size() : 0;
  if (logit_terms > 0 && logit_terms != batch.targets.size())
    throw std::invalid_argument("ae2_batch_loss: " + std::to_string(logit_terms) +
                                " logit sets for " + std::to_string(batch.targets.size()) +
                                " terms; expected one per term");
  if (batch.term_scores.size() != batch.term_codes.size() ||
      batch.targets.size() != batch.term_codes.size())
    throw std::invalid_argument("ae2_batch_loss: " + std::to_string(batch.term_codes.size()) +
                                " term code sets, " + std::to_string(batch.term_scores.size()) +
                                " score sets and " + std::to_string(batch.targets.size()) +
                                " targets; expected one of each per term");
  if (micro_batch < 1)
    throw std::invalid_argument("ae2_batch_loss: micro_batch must be >= 1, got " +
                                std::to_string(micro_batch));
  const std::int64_t n_r = batch.reconstruction.shape()[0];
  for (std::size_t k = 0; k < logit_terms; ++k)
    if (batch.term_logits[k].shape() != Shape{n_r})
      throw std::invalid_argument("ae2_batch_loss: logit set " + std::to_string(k) + " is " +
                                  batch.term_logits[k].shape().str() + "; expected [" +
                                  std::to_string(n_r) + "], one a reconstruction sample");
  std::int64_t total = n_r;
  for (std::size_t k = 0; k < terms; ++k)
    total += batch.term_codes[k].shape()[0];
  // as many parts as the micro-batch size asks for, but never more than the smallest set
  // has rows, so that no part is empty
  std::int64_t smallest = n_r;
  for (std::size_t k = 0; k < terms; ++k)
    smallest = std::min(smallest, batch.term_codes[k].shape()[0]);
  if (smallest < 1)
    throw std::invalid_argument("ae2_batch_loss: a sample set of the batch is empty");
  const std::size_t parts =
      static_cast<std::size_t>(std::min((total + micro_batch - 1) / micro_batch, smallest));
  *micro_batches = parts;
  const std::int64_t d = ae2.spec().latent_dim;
  // each statistic is scaled so that its mean over all `total` rows is its mean over its set
  const float scale_r = static_cast<float>(total) / static_cast<float>(n_r);
  std::vector<float> scale_k;
  for (std::size_t k = 0; k < terms; ++k)
    scale_k.push_back(static_cast<float>(total) /
                      static_cast<float>(batch.term_codes[k].shape()[0]));

  nn::BatchLoss loss;
  loss.outer_is_affine = terms == 0 && logit_terms == 0;
  const bool with_signed = diagonal == SparsityDiagonal::kAbsMean;
  loss.statistics = [&ae2, &batch, parts, terms, logit_terms, d, scale_r, scale_k, with_signed](
                        std::size_t p, bool create_graph) {
    // rows of this part: [reconstruction | term 0 | term 1 | ...]
    const Tensor y_r = part_of(batch.reconstruction, p, parts);
    std::vector<Tensor> jtv(terms), signed_jtv(terms);
    std::vector<std::int64_t> sizes{y_r.defined() ? y_r.shape()[0] : 0};
    for (std::size_t k = 0; k < terms; ++k) {
      const Tensor y = part_of(batch.term_codes[k], p, parts);
      if (y.defined()) {
        signed_jtv[k] = nn::mul_scalar(
            latent_score_differences(ae2, y, part_of(batch.term_scores[k], p, parts), create_graph),
            scale_k[k]);
        jtv[k] = nn::abs(signed_jtv[k]);
      }
      sizes.push_back(y.defined() ? y.shape()[0] : 0);
    }
    std::int64_t rows = 0;
    for (std::int64_t s : sizes)
      rows += s;
    std::vector<Tensor> stats;
    // reconstruction: mean squared error per sample on its rows, 0 elsewhere
    Tensor recon, z_r;
    if (y_r.defined()) {
      z_r = ae2.encode(y_r);
      recon = nn::mul_scalar(
          nn::mean(nn::square(nn::sub(ae2.decode(z_r), ae2.coordinates(y_r))), {1, 2, 3}), scale_r);
    }
    stats.push_back(
        join({recon, rows > sizes[0] ? Tensor::zeros(Shape{rows - sizes[0]}) : Tensor()}));
    // term k's rows of `per_term`, zeros elsewhere: |J_g^T v_k| first, then the signed ones
    const auto place = [&](const std::vector<Tensor>& per_term) {
      std::int64_t before = sizes[0];
      for (std::size_t k = 0; k < terms; ++k) {
        const std::int64_t after = rows - before - sizes[k + 1];
        stats.push_back(join({before > 0 ? Tensor::zeros(Shape{before, d}) : Tensor(), per_term[k],
                              after > 0 ? Tensor::zeros(Shape{after, d}) : Tensor()}));
        before += sizes[k + 1];
      }
    };
    place(jtv);
    if (with_signed)
      place(signed_jtv);
    // the logit term's moments [z, z^2, z l, l, l^2] on the reconstruction rows, 0 elsewhere
    for (std::size_t k = 0; k < logit_terms; ++k) {
      Tensor moments;
      if (y_r.defined()) {
        const std::int64_t n = sizes[0];
        const Tensor z = nn::slice(z_r, 1, batch.targets[k], batch.targets[k] + 1);
        const Tensor l = nn::reshape(part_of(batch.term_logits[k], p, parts), Shape{n, 1});
        moments = nn::mul_scalar(nn::concat({z, nn::square(z), nn::mul(z, l), l, nn::square(l)}, 1),
                                 scale_r);
      }
      stats.push_back(
          join({moments, rows > sizes[0] ? Tensor::zeros(Shape{rows - sizes[0], 5}) : Tensor()}));
    }
    return stats;
  };
  const std::vector<std::int64_t> targets = batch.targets;
  const float logit_weight = static_cast<float>(batch.logit_weight);
  loss.outer = [terms, logit_terms, lambda, norm, targets, with_signed,
                logit_weight](const std::vector<Tensor>& means) {
    Tensor l = means[0];
    for (std::size_t k = 0; k < terms; ++k)
      l = nn::add(l, nn::mul_scalar(sparsity_penalty(means[1 + k], targets[k], norm,
                                                     with_signed ? means[1 + terms + k] : Tensor()),
                                    static_cast<float>(lambda)));
    const std::size_t first_logit = means.size() - logit_terms;
    for (std::size_t k = 0; k < logit_terms; ++k)
      l = nn::add(l, nn::mul_scalar(logit_correlation_loss(means[first_logit + k]), logit_weight));
    return l;
  };
  return loss;
}

}  // namespace ropes::crl
