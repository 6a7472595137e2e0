// Example from the ropes_eval README: per-joint MCC of latents that recover two joints up to
// an affine map (joint 0) and a monotonic but nonlinear map (joint 1).
#include <ropes_eval/correlation.hpp>

#include <cstdio>

int main() {
  const int n = 200;
  Eigen::MatrixXd angles(n, 2), latents(n, 2);
  for (int i = 0; i < n; ++i) {
    const double t = -1.5 + 3.0 * i / (n - 1);
    angles(i, 0) = t;
    angles(i, 1) = 0.5 * t;
    latents(i, 0) = -2.0 * t + 0.3;  // affine: |Pearson| = 1
    latents(i, 1) = t * t * t;       // monotonic: Spearman = 1, Pearson < 1
  }
  const Eigen::VectorXd r = ropes::eval::per_joint_correlation(latents, angles);
  const Eigen::VectorXd rho =
      ropes::eval::per_joint_correlation(latents, angles, ropes::eval::Correlation::kSpearman);
  std::printf("joint 0: |pearson| %.4f |spearman| %.4f\n", r(0), rho(0));
  std::printf("joint 1: |pearson| %.4f |spearman| %.4f\n", r(1), rho(1));
  std::printf("MCC (pearson, the paper's): %.4f\n", r.mean());
  return rho(1) > 0.9999 && r(1) < rho(1) ? 0 : 1;
}
