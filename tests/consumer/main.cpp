// Uses ropes_nn and ropes_eval from their install space: draws two correlated samples and
// checks their correlation, so linking and running both libraries is exercised.
#include <ropes_eval/correlation.hpp>
#include <ropes_nn/philox.hpp>

#include <cstdio>

int main() {
  ropes::nn::PhiloxStream rng(/*seed=*/5, /*stream=*/0);
  const int n = 5000;
  Eigen::VectorXd x(n), y(n);
  for (int i = 0; i < n; ++i) {
    x(i) = rng.normal();
    y(i) = 0.6 * x(i) + 0.8 * rng.normal();  // population correlation 0.6
  }
  const double r = ropes::eval::pearson(x, y);
  std::printf("consumer: pearson %.4f (population 0.6)\n", r);
  return r > 0.55 && r < 0.65 ? 0 : 1;
}
