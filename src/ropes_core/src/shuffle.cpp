#include "ropes_core/dataset.hpp"
#include "ropes_core/philox.hpp"

namespace ropes::core {

namespace {

// the bounded draw of shuffled_indices: uniform on [0, bound), by rejection
std::uint64_t uniform_below(PhiloxStream& rng, std::uint64_t bound) {
  if (bound <= 0xffffffffull) {
    const auto b = static_cast<std::uint32_t>(bound);
    const std::uint32_t threshold = static_cast<std::uint32_t>(-b) % b;  // 2^32 mod bound
    while (true) {
      const std::uint32_t w = rng.next_u32();
      if (w >= threshold)
        return w % b;
    }
  }
  const std::uint64_t threshold = (0 - bound) % bound;  // 2^64 mod bound
  while (true) {
    const std::uint64_t low = rng.next_u32();
    const std::uint64_t w = low | static_cast<std::uint64_t>(rng.next_u32()) << 32;
    if (w >= threshold)
      return w % bound;
  }
}

}  // namespace

std::vector<std::int64_t> shuffled_indices(std::int64_t n, std::uint64_t seed,
                                           std::uint64_t epoch) {
  if (n < 0) {
    throw std::invalid_argument("shuffled_indices: n = " + std::to_string(n) + "; expected n >= 0");
  }
  std::vector<std::int64_t> order(static_cast<std::size_t>(n));
  for (std::int64_t i = 0; i < n; ++i)
    order[static_cast<std::size_t>(i)] = i;
  // Fisher-Yates from the back
  PhiloxStream rng(seed, kShuffleStreamBase + epoch);
  for (std::int64_t i = n - 1; i > 0; --i) {
    const std::uint64_t j = uniform_below(rng, static_cast<std::uint64_t>(i) + 1);
    std::swap(order[static_cast<std::size_t>(i)], order[static_cast<std::size_t>(j)]);
  }
  return order;
}

}  // namespace ropes::core
