// Example from the ropes_nn README: one Philox stream per unit of work, so the numbers a
// unit sees do not depend on which thread runs it or in what order.
#include <ropes_nn/philox.hpp>

#include <cstdio>

int main() {
  const std::uint64_t seed = 42;
  double total = 0.0;
  for (std::uint64_t sample = 0; sample < 4; ++sample) {
    ropes::nn::PhiloxStream rng(seed, /*stream=*/sample);
    const double u = rng.uniform_double();
    const double z = rng.normal();
    std::printf("sample %llu: uniform %.6f normal %+.6f\n", static_cast<unsigned long long>(sample),
                u, z);
    total += u;
  }
  // the same (seed, stream) always gives the same first number
  ropes::nn::PhiloxStream again(seed, 0);
  ropes::nn::PhiloxStream first(seed, 0);
  return again.uniform_double() == first.uniform_double() && total > 0.0 ? 0 : 1;
}
