// Example from the ropes_core README: one Philox stream per unit of work, so the numbers a
// unit sees do not depend on which thread runs it or in what order.
#include <ropes_core/philox.hpp>

#include <cstdio>
#include <vector>

// the first normal of each sample's stream, visiting samples in the given order
std::vector<double> draw(const std::vector<int>& order, std::uint64_t seed) {
  std::vector<double> first_normal(order.size());
  for (int sample : order) {
    ropes::core::PhiloxStream rng(seed, /*stream=*/static_cast<std::uint64_t>(sample));
    first_normal[static_cast<std::size_t>(sample)] = rng.normal();
  }
  return first_normal;
}

int main() {
  const std::vector<double> forward = draw({0, 1, 2, 3}, 42);
  const std::vector<double> shuffled = draw({2, 0, 3, 1}, 42);
  for (std::size_t i = 0; i < forward.size(); ++i) {
    std::printf("sample %zu: normal %+.6f (shuffled order: %+.6f)\n", i, forward[i], shuffled[i]);
  }
  // same numbers whatever the order; a different seed gives different ones
  return forward == shuffled && draw({0}, 43)[0] != forward[0] ? 0 : 1;
}
