#include "ropes_crl/sparsity_objective.hpp"

#include <ropes_core/philox.hpp>
#include <ropes_nn/ops.hpp>
#include <ropes_nn/train_step.hpp>

#include <gtest/gtest.h>

#include <Eigen/Core>

#include <cmath>

using namespace ropes::crl;
using ropes::nn::Shape;
using ropes::nn::Tensor;

namespace {

Tensor normal(const Shape& s, std::uint64_t stream, float scale = 1.0f) {
  ropes::core::PhiloxStream rng(99, stream);
  std::vector<float> v(static_cast<std::size_t>(s.numel()));
  for (float& x : v)
    x = scale * static_cast<float>(rng.normal());
  return Tensor(s, v);
}

struct Fixture {
  std::unique_ptr<Ae2> net;
  Ae2Batch batch;
};

// a small AE2 (MLP, SiLU: smooth, so central differences converge) and one batch with two
// sparsity terms, targets 0 and 2
// With input_normalization "standardize" the map is fitted on the reconstruction codes,
// whose elements are then given spreads from 0 (constant) to 2.
Fixture make(const std::string& normalization, const std::string& input_normalization = "none") {
  Ae2Spec s;
  s.kind = "mlp";
  s.widths = {8};
  s.activation = "silu";
  s.latent_dim = 4;
  s.input_normalization = input_normalization;
  Fixture f;
  f.net = std::make_unique<Ae2>(s);
  f.net->initialize(5);
  f.batch.reconstruction = normal(Shape{5, 1, 8, 8}, 1);
  if (input_normalization == "standardize") {
    float* y = f.batch.reconstruction.mutable_data();
    for (std::int64_t i = 0; i < 5 * 64; ++i)
      y[i] = (i % 64 == 0) ? 0.25f : y[i] * static_cast<float>(i % 64) / 32.0f;
    CodeStandardization fitted(1, 8);
    fitted.fit(f.batch.reconstruction, "test");
    f.net->set_input_map(fitted);
  }
  for (int k = 0; k < 2; ++k) {
    f.batch.term_codes.push_back(normal(Shape{6, 1, 8, 8}, 10 + k));
    Tensor v = normal(Shape{6, 1, 8, 8}, 20 + k, 0.3f);
    f.batch.term_scores.push_back(normalization == "unit" ? unit_length_rows(v) : v);
  }
  f.batch.targets = {0, 2};
  return f;
}

// the loss in double precision from the pieces: mean reconstruction error, then the
// reference score_sparsity_loss of the J_g^T v rows (independent of the autodiff outer)
double reference_loss(Fixture& f, double lambda, SparsityNorm norm, SparsityDiagonal diagonal) {
  ropes::nn::GradModeGuard no_grad(true);
  const Tensor y = f.batch.reconstruction;
  const Tensor err = ropes::nn::square(ropes::nn::sub((*f.net)(y), f.net->coordinates(y)));
  double recon = 0;
  for (std::int64_t i = 0; i < err.numel(); ++i)
    recon += err.data()[i];
  double loss = recon / static_cast<double>(err.numel());
  for (std::size_t k = 0; k < f.batch.term_codes.size(); ++k) {
    const Tensor j =
        latent_score_differences(*f.net, f.batch.term_codes[k], f.batch.term_scores[k], false);
    Eigen::MatrixXd rows(j.shape()[0], j.shape()[1]);
    for (std::int64_t r = 0; r < rows.rows(); ++r)
      for (std::int64_t c = 0; c < rows.cols(); ++c)
        rows(r, c) = j.data()[r * rows.cols() + c];
    loss +=
        lambda * score_sparsity_loss(rows, static_cast<int>(f.batch.targets[k]), norm, diagonal);
  }
  // ae2.logit_loss: 1 - the Pearson correlation of latent t_k with logit set k over the
  // reconstruction samples, from double sums (not the autodiff moments)
  if (f.batch.logit_weight > 0) {
    const Tensor z = f.net->encode(y);
    const std::int64_t n = z.shape()[0], d = z.shape()[1];
    for (std::size_t k = 0; k < f.batch.term_logits.size(); ++k) {
      double sz = 0, sl = 0;
      for (std::int64_t i = 0; i < n; ++i) {
        sz += z.data()[i * d + f.batch.targets[k]];
        sl += f.batch.term_logits[k].data()[i];
      }
      double cov = 0, vz = 0, vl = 0;
      for (std::int64_t i = 0; i < n; ++i) {
        const double a = z.data()[i * d + f.batch.targets[k]] - sz / static_cast<double>(n);
        const double b = f.batch.term_logits[k].data()[i] - sl / static_cast<double>(n);
        cov += a * b;
        vz += a * a;
        vl += b * b;
      }
      loss += f.batch.logit_weight * (1.0 - cov / std::sqrt(vz * vl));
    }
  }
  return loss;
}

// the logit term's inputs: a logit per reconstruction sample per term
void add_logits(Fixture& f, double weight) {
  f.batch.logit_weight = weight;
  for (std::uint64_t k = 0; k < f.batch.targets.size(); ++k)
    f.batch.term_logits.push_back(normal(Shape{f.batch.reconstruction.shape()[0]}, 30 + k));
}

// The gradient the training step uses (two phases over 2 micro-batches) against central
// finite differences of the double-precision reference loss, every entry of the trained
// parameters.
void expect_gradient_matches(Fixture& f, SparsityNorm norm, SparsityDiagonal diagonal,
                             const std::string& label, double lambda = 0.7,
                             std::int64_t micro_batch = 9) {
  std::size_t parts = 0;
  const ropes::nn::BatchLoss loss =
      ae2_batch_loss(*f.net, f.batch, lambda, norm, micro_batch, &parts, diagonal);
  ASSERT_EQ(parts, 2u);
  std::vector<Tensor> params;
  for (const auto& named : f.net->trained_parameters())
    params.push_back(named.second);
  const ropes::nn::BatchGradient g = ropes::nn::batch_gradient(params, loss, parts);
  EXPECT_NEAR(g.loss, reference_loss(f, lambda, norm, diagonal), 1e-5 * std::fabs(g.loss));
  const double h = 1e-3;
  double worst = 0;
  std::size_t checked = 0;
  for (std::size_t p = 0; p < params.size(); ++p) {
    Tensor t = params[p];
    for (std::int64_t i = 0; i < t.numel(); ++i) {
      const float saved = t.data()[i];
      t.mutable_data()[i] = saved + static_cast<float>(h);
      const double up = reference_loss(f, lambda, norm, diagonal);
      t.mutable_data()[i] = saved - static_cast<float>(h);
      const double down = reference_loss(f, lambda, norm, diagonal);
      t.mutable_data()[i] = saved;
      const double numeric = (up - down) / (2 * h);
      const double analytic = g.grads[p].data()[i];
      const double err = std::fabs(analytic - numeric);
      worst = std::max(worst, err);
      EXPECT_LE(err, 2e-3 + 2e-2 * std::fabs(numeric))
          << label << ": parameter " << p << " entry " << i << ": analytic " << analytic
          << ", finite differences " << numeric;
      ++checked;
    }
  }
  std::printf("%s: %zu entries, max |analytic - numeric| %.2e\n", label.c_str(), checked, worst);
}

}  // namespace

// both norms, both score normalisations and both forms of the diagonal
TEST(SparsityObjective, GradientMatchesFiniteDifferences) {
  for (const SparsityNorm norm : {SparsityNorm::kL2Squared, SparsityNorm::kL1}) {
    for (const std::string normalization : {"none", "unit"}) {
      for (const SparsityDiagonal diagonal :
           {SparsityDiagonal::kMeanAbs, SparsityDiagonal::kAbsMean}) {
        Fixture f = make(normalization);
        expect_gradient_matches(
            f, norm, diagonal,
            std::string(to_string(norm)) + ", " + normalization + ", " + to_string(diagonal));
      }
    }
  }
}

// an AE2 that reads standardised codes: the reconstruction is compared in its coordinates
// and the fixed map gets no gradient (it is not among the trained parameters)
TEST(SparsityObjective, GradientMatchesFiniteDifferencesWithStandardizedCodes) {
  for (const SparsityNorm norm : {SparsityNorm::kL2Squared, SparsityNorm::kL1}) {
    Fixture f = make("unit", "standardize");
    EXPECT_EQ(f.net->trained_parameters().size() + 2, f.net->named_parameters().size());
    expect_gradient_matches(f, norm, SparsityDiagonal::kAbsMean,
                            std::string(to_string(norm)) + ", unit, abs_mean, standardize");
  }
}

// ae2.logit_loss (an extension) beside the sparsity terms, and alone (lambda 0): its
// correlation moments are batch means, so the finite differences of the whole-batch
// reference check the split into micro-batches too
TEST(SparsityObjective, GradientMatchesFiniteDifferencesWithTheLogitTerm) {
  for (const double lambda : {0.7, 0.0}) {
    Fixture f = make("unit");
    add_logits(f, 0.5);
    expect_gradient_matches(f, SparsityNorm::kL2Squared, SparsityDiagonal::kAbsMean,
                            "l2sq, unit, abs_mean, logit 0.5, lambda " + std::to_string(lambda),
                            lambda, lambda > 0 ? 9 : 3);  // 17 rows, or the 5 reconstruction ones
  }
}

TEST(SparsityObjective, TheLogitTermIsOneMinusTheCorrelation) {
  // a perfectly correlated latent gives 0, an anti-correlated one 2, a constant one 1
  const auto loss_of = [](std::vector<float> m) {
    return logit_correlation_loss(Tensor(Shape{5}, std::move(m))).item();
  };
  // z = 2 l + 1 with E l = 0.5, E l^2 = 1.25: E z = 2, E z^2 = 4 E l^2 + 4 E l + 1 = 8,
  // E z l = 2 E l^2 + E l = 3
  EXPECT_NEAR(loss_of({2.0f, 8.0f, 3.0f, 0.5f, 1.25f}), 0.0, 1e-6);
  EXPECT_NEAR(loss_of({-2.0f, 8.0f, -3.0f, 0.5f, 1.25f}), 2.0, 1e-6);
  EXPECT_NEAR(loss_of({3.0f, 9.0f, 1.5f, 0.5f, 1.25f}), 1.0, 1e-6);
  // a set per term, of the reconstruction samples' count
  Fixture f = make("unit");
  add_logits(f, 1.0);
  const auto expect_refused = [&f](const std::string& what, const std::string& message) {
    std::size_t parts = 0;
    try {
      ae2_batch_loss(*f.net, f.batch, 1.0, SparsityNorm::kL2Squared, 9, &parts);
      ADD_FAILURE() << what << " was accepted";
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find(message), std::string::npos) << e.what();
    }
  };
  f.batch.term_logits.pop_back();
  expect_refused("one logit set for two terms", "1 logit sets for 2 terms");
  f.batch.term_logits = {normal(Shape{4}, 40), normal(Shape{5}, 41)};
  expect_refused("a logit set of 4 for 5 samples", "logit set 0 is [4]; expected [5]");
}

// the batch mean sits inside the norm: any micro-batch split gives the whole-batch gradient
TEST(SparsityObjective, MicroBatchesGiveTheWholeBatchGradient) {
  Fixture f = make("unit");
  const std::vector<Tensor> params = f.net->parameters();
  std::size_t one = 0, many = 0;
  const ropes::nn::BatchLoss whole_loss =
      ae2_batch_loss(*f.net, f.batch, 1.0, SparsityNorm::kL2Squared, 100, &one);
  const ropes::nn::BatchLoss split_loss =
      ae2_batch_loss(*f.net, f.batch, 1.0, SparsityNorm::kL2Squared, 4, &many);
  const auto whole = ropes::nn::batch_gradient(params, whole_loss, one);
  const auto split = ropes::nn::batch_gradient(params, split_loss, many);
  ASSERT_EQ(one, 1u);
  ASSERT_EQ(many, 5u);  // 17 rows, at most 4 a part
  EXPECT_NEAR(whole.loss, split.loss, 1e-5 * whole.loss);
  for (std::size_t p = 0; p < params.size(); ++p)
    for (std::int64_t i = 0; i < params[p].numel(); ++i)
      EXPECT_NEAR(whole.grads[p].data()[i], split.grads[p].data()[i], 1e-5)
          << "parameter " << p << " entry " << i;
}

TEST(SparsityObjective, UnitLengthRowsAndPenalty) {
  const Tensor v(Shape{2, 2}, {3.0f, 4.0f, 0.0f, 0.0f});
  EXPECT_EQ(unit_length_rows(v).to_vector(), (std::vector<float>{0.6f, 0.8f, 0.0f, 0.0f}));
  // lengths 5, 0 and 10: mean 5, so every row is divided by 5 and keeps its size relative
  // to the others
  const Tensor w(Shape{3, 2}, {3.0f, 4.0f, 0.0f, 0.0f, -6.0f, 8.0f});
  EXPECT_EQ(mean_unit_length_rows(w).to_vector(),
            (std::vector<float>{0.6f, 0.8f, 0.0f, 0.0f, -1.2f, 1.6f}));
  EXPECT_EQ(mean_unit_length_rows(Tensor(Shape{2, 2}, {0.0f, 0.0f, 0.0f, 0.0f})).to_vector(),
            (std::vector<float>(4, 0.0f)));
  const Tensor m(Shape{3}, {0.5f, 0.25f, 1.0f});
  EXPECT_FLOAT_EQ(sparsity_penalty(m, 0, SparsityNorm::kL2Squared).item(), 0.25f + 0.0625f + 1.0f);
  EXPECT_FLOAT_EQ(sparsity_penalty(m, 2, SparsityNorm::kL1).item(), 0.75f);
  EXPECT_THROW(sparsity_penalty(m, 3, SparsityNorm::kL1), std::invalid_argument);
  // the signed mean's magnitude stands for the target entry: (0.5, 0.25, |-0.5| - 1)
  const Tensor signed_mean(Shape{3}, {0.1f, -0.2f, -0.5f});
  EXPECT_FLOAT_EQ(sparsity_penalty(m, 2, SparsityNorm::kL2Squared, signed_mean).item(),
                  0.25f + 0.0625f + 0.25f);
  EXPECT_THROW(sparsity_penalty(m, 2, SparsityNorm::kL1, Tensor(Shape{2}, {1.0f, 1.0f})),
               std::invalid_argument);
}
