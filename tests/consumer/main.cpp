// Uses ropes_core, ropes_nn, ropes_crl and ropes_eval from their install space: hashes FIPS
// 180-2's "abc" with ropes_core's SHA-256, draws two correlated
// samples and checks their correlation and best assignment, and builds the networks of an installed
// ROPES config, so linking and running the libraries (and finding installed configs) is exercised.
// Encodes a batch with AE1 (the kernels' GEMM) and prints the instruction-set level the kernels
// ran at and a checksum of the code: consumer_test.sh runs it again with ROPES_ISA=v3.
#include <ropes_core/philox.hpp>
#include <ropes_core/sha256.hpp>
#include <ropes_crl/experiment_config.hpp>
#include <ropes_crl/networks.hpp>
#include <ropes_eval/correlation.hpp>
#include <ropes_nn/build_info.hpp>

#include <cstdio>
#include <string>
#include <vector>

int main() {
  // FIPS 180-2, appendix B.1
  const std::string abc = ropes::core::sha256_hex("abc", 3);
  std::printf("consumer: sha256(\"abc\") %s\n", abc.c_str());
  if (abc != "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad")
    return 1;
  ropes::core::PhiloxStream rng(/*seed=*/5, /*stream=*/0);
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
  ae1.initialize(7);
  std::vector<float> pixels(static_cast<std::size_t>(4 * config.image_size * config.image_size));
  for (float& v : pixels)
    v = static_cast<float>(rng.uniform_double());
  const ropes::nn::Tensor code = ae1.encode(
      ropes::nn::Tensor(ropes::nn::Shape{4, 1, config.image_size, config.image_size}, pixels));
  double checksum = 0;
  for (float v : code.to_vector())
    checksum += v;
  std::printf("consumer: kernels %s (build %s, baseline %s); AE1 code checksum %.6f\n",
              ropes::nn::build_info().isa_level.c_str(), ropes::nn::build_info().isa_build.c_str(),
              ropes::nn::build_info().isa_baseline.c_str(), checksum);
  const bool swapped = best.latent_of_joint[0] == 1 && best.latent_of_joint[1] == 0;
  return r > 0.55 && r < 0.65 && swapped && ae1.parameter_count() > 0 ? 0 : 1;
}
