// Parity with PyTorch 1.13 (Debian's python3-torch): outputs and gradients of each
// operation, of ResBlockGN, of the score-sparsity loss's double backward through a small
// decoder, and of Adam. Reference values: test/fixtures/torch_parity.safetensors, written
// by test/make_torch_fixtures.py (which documents how to regenerate them).
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <string>

#include "ropes_nn/adam.hpp"
#include "ropes_nn/layers.hpp"
#include "ropes_nn/ops.hpp"
#include "ropes_nn/safetensors.hpp"

namespace ropes::nn {
namespace {

const Safetensors& fixture() {
  static const Safetensors file =
      read_safetensors(std::string(ROPES_NN_TEST_FIXTURES) + "/torch_parity.safetensors");
  return file;
}

// a fixture tensor as a leaf (requires_grad when asked)
Tensor T(const std::string& name, bool requires_grad = false) {
  const core::NpyArray* a = fixture().find(name);
  if (!a)
    throw std::runtime_error("fixture has no tensor " + name);
  std::vector<float> values(a->data.size() / sizeof(float));
  if (!values.empty())
    std::memcpy(values.data(), a->data.data(), a->data.size());
  return Tensor(Shape(a->shape), values, requires_grad);
}

void expect_close(const Tensor& ours, const Tensor& theirs, const std::string& what,
                  double atol = 1e-5, double rtol = 1e-4) {
  // PyTorch's 0-d results are kept as shape [] or [1]; anything else must match exactly
  if (ours.numel() != 1 || theirs.numel() != 1) {
    ASSERT_EQ(ours.shape(), theirs.shape()) << what;
  }
  double worst = 0.0;
  std::int64_t at = 0;
  for (std::int64_t i = 0; i < ours.numel(); ++i) {
    const double excess = std::abs(static_cast<double>(ours.data()[i]) - theirs.data()[i]) -
                          (atol + rtol * std::abs(theirs.data()[i]));
    if (!(excess <= worst)) {  // a NaN on either side fails too
      worst = excess;
      at = i;
    }
  }
  EXPECT_EQ(worst, 0.0) << what << ": element " << at << " is " << ours.data()[at]
                        << ", PyTorch has " << theirs.data()[at];
}

Tensor weighted_sum(const Tensor& y, const Tensor& r) {
  return sum(mul(y, r));
}

TEST(TorchParityGolden, Conv2dStride2WithFlaxSamePadding) {
  Tensor x = T("conv.x", true), w = T("conv.w", true), b = T("conv.b", true);
  const Tensor y = add(conv2d(x, w, 2), reshape(b, Shape{1, 4, 1, 1}));
  expect_close(y, T("conv.y"), "conv.y");
  const auto g = grad({weighted_sum(y, T("conv.r"))}, {x, w, b});
  expect_close(g[0], T("conv.grad_x"), "conv.grad_x");
  expect_close(g[1], T("conv.grad_w"), "conv.grad_w");
  expect_close(g[2], T("conv.grad_b"), "conv.grad_b");
}

TEST(TorchParityGolden, ConvTranspose2dKernel4Stride2Same) {
  Tensor x = T("convt.x", true), w = T("convt.w", true), b = T("convt.b", true);
  const Tensor y = add(conv_transpose2d(x, w, 2), reshape(b, Shape{1, 2, 1, 1}));
  expect_close(y, T("convt.y"), "convt.y");
  const auto g = grad({weighted_sum(y, T("convt.r"))}, {x, w, b});
  expect_close(g[0], T("convt.grad_x"), "convt.grad_x");
  expect_close(g[1], T("convt.grad_w"), "convt.grad_w");
  expect_close(g[2], T("convt.grad_b"), "convt.grad_b");
}

TEST(TorchParityGolden, GroupNorm) {
  Tensor x = T("gn.x", true), gamma = T("gn.gamma", true), beta = T("gn.beta", true);
  const Tensor y = group_norm(x, 2, gamma, beta, 1e-5f);
  expect_close(y, T("gn.y"), "gn.y");
  const auto g = grad({weighted_sum(y, T("gn.r"))}, {x, gamma, beta});
  expect_close(g[0], T("gn.grad_x"), "gn.grad_x");
  expect_close(g[1], T("gn.grad_gamma"), "gn.grad_gamma");
  expect_close(g[2], T("gn.grad_beta"), "gn.grad_beta");
}

TEST(TorchParityGolden, DenseBceWithLogitsAndMse) {
  Tensor x = T("bce.x", true), w = T("bce.w", true), b = T("bce.b", true);
  const Tensor loss = bce_with_logits(add(matmul(x, w), b), T("bce.t"));
  expect_close(loss, T("bce.loss"), "bce.loss");
  const auto g = grad({loss}, {x, w, b});
  expect_close(g[0], T("bce.grad_x"), "bce.grad_x");
  expect_close(g[1], T("bce.grad_w"), "bce.grad_w");
  expect_close(g[2], T("bce.grad_b"), "bce.grad_b");
  Tensor a = T("mse.a", true);
  const Tensor mse = mse_loss(a, T("mse.t"));
  expect_close(mse, T("mse.loss"), "mse.loss");
  expect_close(grad({mse}, {a})[0], T("mse.grad_a"), "mse.grad_a");
}

TEST(TorchParityGolden, ResBlockGNModuleWithNamedParameters) {
  ResBlockGN block(4, 2);
  // the module's own names are the fixture's keys
  for (auto& [name, p] : block.named_parameters()) {
    const Tensor ref = T("resblock." + name);
    ASSERT_EQ(p.shape(), ref.shape()) << name;
    std::memcpy(p.mutable_data(), ref.data(), static_cast<std::size_t>(p.numel()) * 4);
    block.mark_initialized(name);
  }
  Tensor x = T("resblock.x", true);
  const Tensor y = block(x);
  expect_close(y, T("resblock.y"), "resblock.y");
  std::vector<Tensor> wrt = {x};
  for (auto& [name, p] : block.named_parameters())
    wrt.push_back(p);
  const auto g = grad({weighted_sum(y, T("resblock.r"))}, wrt);
  expect_close(g[0], T("resblock.grad_x"), "resblock.grad_x");
  std::size_t k = 1;
  for (auto& [name, p] : block.named_parameters()) {
    expect_close(g[k++], T("resblock.grad." + name), "resblock.grad." + name, 1e-4, 1e-3);
  }
}

// The AE2 loss: || E|J_g(z)^T v| - e_1 ||^2, differentiated with respect to the decoder's
// and the encoder's parameters (a gradient of a gradient).
TEST(TorchParityGolden, ScoreSparsityDoubleBackwardThroughADecoder) {
  const char* names[] = {"enc_w", "enc_b", "w1", "b1", "w2", "b2", "gamma", "beta", "w3", "b3"};
  std::vector<Tensor> params;
  for (const char* n : names)
    params.push_back(T(std::string("sparsity.") + n, true));
  const Tensor &enc_w = params[0], &enc_b = params[1], &w1 = params[2], &b1 = params[3],
               &w2 = params[4], &b2 = params[5], &gamma = params[6], &beta = params[7],
               &w3 = params[8], &b3 = params[9];
  const Tensor z = add(matmul(T("sparsity.y_in"), enc_w), enc_b);  // [3, 2]
  Tensor h = reshape(relu(add(matmul(z, w1), b1)), Shape{3, 4, 2, 2});
  h = add(conv_transpose2d(h, w2, 2), reshape(b2, Shape{1, 2, 1, 1}));
  h = relu(group_norm(h, 1, gamma, beta, 1e-6f));
  const Tensor out = add(conv2d(h, w3), reshape(b3, Shape{1, 1, 1, 1}));
  const Tensor jtv = grad({out}, {z}, {T("sparsity.v")}, /*create_graph=*/true)[0];
  expect_close(jtv, T("sparsity.jtv"), "sparsity.jtv");
  const Tensor target(Shape{2}, {0.0f, 1.0f});
  const Tensor loss = sum(square(sub(mean(abs(jtv), {0}), target)));
  expect_close(loss, T("sparsity.loss"), "sparsity.loss");
  const auto g = grad({loss}, params, {}, false, /*allow_unused=*/true);
  for (std::size_t i = 0; i < params.size(); ++i) {
    expect_close(g[i], T(std::string("sparsity.grad_") + names[i]),
                 std::string("sparsity.grad_") + names[i], 1e-4, 1e-3);
  }
}

TEST(TorchParityGolden, AdamWithWeightDecay) {
  Tensor p = T("adam.p0", true);
  Adam adam({p}, AdamOptions{0.01, 0.9, 0.999, 1e-8, 0.1});
  for (const char* g : {"adam.g0", "adam.g1", "adam.g2"})
    adam.step({T(g)});
  EXPECT_EQ(adam.steps(), 3);
  expect_close(p, T("adam.p3"), "adam.p3", 1e-6, 1e-5);
}

}  // namespace
}  // namespace ropes::nn
