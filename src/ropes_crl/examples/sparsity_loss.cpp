// Example from the ropes_crl README: how far a batch of latent-space score differences for
// an intervention on latent 0 is from the one-sparse ideal the paper's loss asks for.
#include <ropes_crl/score_sparsity.hpp>

#include <cstdio>

int main() {
  Eigen::MatrixXd diffs(3, 3);  // [n samples, d latents]
  diffs << 1.2, 0.1, -0.05,     //
      -0.9, -0.2, 0.0,          //
      1.1, 0.0, 0.1;
  const double l2sq = ropes::crl::score_sparsity_loss(diffs, /*target=*/0);
  const double l1 = ropes::crl::score_sparsity_loss(diffs, 0, ropes::crl::SparsityNorm::kL1);
  std::printf("sparsity loss for latent 0: l2sq %.5f, l1 %.5f\n", l2sq, l1);
  return l2sq > 0.0 && l2sq < l1 ? 0 : 1;
}
