// Example from the ropes_sim README: sample the observational distribution of joint 2 in the
// paper's single-camera table, TN_[-1.5, 1.5](0, 1), and compare with the closed forms.
#include <ropes_sim/truncated_normal.hpp>

#include <cmath>
#include <cstdio>

int main() {
  const ropes::sim::TruncatedNormal joint2(/*mu=*/0.0, /*sigma=*/1.0, /*lower=*/-1.5,
                                           /*upper=*/1.5);
  ropes::core::PhiloxStream rng(/*seed=*/1, /*stream=*/0);
  const int n = 100000;
  double sum = 0.0, sum_sq = 0.0;
  for (int i = 0; i < n; ++i) {
    const double q = joint2.sample(rng);
    sum += q;
    sum_sq += q * q;
  }
  const double mean = sum / n;
  const double var = sum_sq / n - mean * mean;
  std::printf("TN[-1.5,1.5](0,1): sample mean %+.4f (exact %+.4f), variance %.4f (exact %.4f)\n",
              mean, joint2.mean(), var, joint2.variance());
  return std::abs(var - joint2.variance()) < 0.01 ? 0 : 1;
}
