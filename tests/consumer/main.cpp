// Uses ropes_nn, ropes_crl and ropes_eval from their install space: draws two correlated
// samples and checks their correlation and best assignment, and builds the networks of an installed
// ROPES config, so linking and running the libraries (and finding installed configs) is exercised.
#include <ropes_crl/experiment_config.hpp>
#include <ropes_crl/networks.hpp>
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
  // latents in the other order: the best assignment swaps them back
  Eigen::MatrixXd latents(n, 2), angles(n, 2);
  latents << y, x;
  angles << x, y;
  const ropes::eval::Assignment best = ropes::eval::best_assignment_correlation(latents, angles);
  std::printf("consumer: best assignment joint 0 -> latent %lld, joint 1 -> latent %lld\n",
              static_cast<long long>(best.latent_of_joint[0]),
              static_cast<long long>(best.latent_of_joint[1]));
  const ropes::crl::ExperimentConfig config = ropes::crl::load_experiment_config("1c-small");
  ropes::crl::Ae1 ae1(config.ae1);
  ropes::crl::Ae2 ae2(config.ae2);
  std::printf("consumer: %s: AE1 %lld parameters, AE2 %lld\n", config.name.c_str(),
              static_cast<long long>(ae1.parameter_count()),
              static_cast<long long>(ae2.parameter_count()));
  const bool swapped = best.latent_of_joint[0] == 1 && best.latent_of_joint[1] == 0;
  return r > 0.55 && r < 0.65 && swapped && ae1.parameter_count() > 0 ? 0 : 1;
}
