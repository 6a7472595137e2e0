#include "ropes_core/philox.hpp"

#include <cmath>
#include <stdexcept>
#include <string>

namespace ropes::core {

namespace {

// multipliers and Weyl increments of Philox4x32 (Salmon et al. 2011, table 2)
constexpr std::uint32_t kMul0 = 0xD2511F53u;
constexpr std::uint32_t kMul1 = 0xCD9E8D57u;
constexpr std::uint32_t kWeyl0 = 0x9E3779B9u;
constexpr std::uint32_t kWeyl1 = 0xBB67AE85u;
constexpr double kTwoPi = 6.283185307179586476925286766559;

inline void mul_hi_lo(std::uint32_t a, std::uint32_t b, std::uint32_t* hi, std::uint32_t* lo) {
  const std::uint64_t product = static_cast<std::uint64_t>(a) * b;
  *hi = static_cast<std::uint32_t>(product >> 32);
  *lo = static_cast<std::uint32_t>(product);
}

}  // namespace

PhiloxCounter philox4x32_10(const PhiloxCounter& counter, const PhiloxKey& key) {
  PhiloxCounter x = counter;
  PhiloxKey k = key;
  for (int round = 0; round < 10; ++round) {
    // one S-box round: two 32x32->64 multiplies, then mix with the key
    std::uint32_t hi0 = 0, lo0 = 0, hi1 = 0, lo1 = 0;
    mul_hi_lo(kMul0, x[0], &hi0, &lo0);
    mul_hi_lo(kMul1, x[2], &hi1, &lo1);
    x = {hi1 ^ x[1] ^ k[0], lo1, hi0 ^ x[3] ^ k[1], lo0};
    // bump the key between rounds
    k[0] += kWeyl0;
    k[1] += kWeyl1;
  }
  return x;
}

PhiloxStream::PhiloxStream(std::uint64_t seed, std::uint64_t stream)
    : seed_(seed),
      stream_(stream),
      key_{static_cast<std::uint32_t>(seed), static_cast<std::uint32_t>(seed >> 32)} {}

void PhiloxStream::refill() {
  const PhiloxCounter counter = {
      static_cast<std::uint32_t>(block_), static_cast<std::uint32_t>(block_ >> 32),
      static_cast<std::uint32_t>(stream_), static_cast<std::uint32_t>(stream_ >> 32)};
  buffer_ = philox4x32_10(counter, key_);
  ++block_;
  used_ = 0;
}

std::uint32_t PhiloxStream::next_u32() {
  if (used_ == 4) {
    refill();
  }
  ++words_drawn_;
  return buffer_[used_++];
}

float PhiloxStream::uniform_float() {
  // top 24 bits: exactly representable, so the result is never rounded up to 1
  return static_cast<float>(next_u32() >> 8) * (1.0f / 16777216.0f);
}

double PhiloxStream::uniform_double() {
  const std::uint64_t hi = next_u32() >> 5;  // 27 bits
  const std::uint64_t lo = next_u32() >> 6;  // 26 bits
  return static_cast<double>((hi << 26) | lo) * (1.0 / 9007199254740992.0);
}

double PhiloxStream::normal() {
  if (has_spare_normal_) {
    has_spare_normal_ = false;
    return spare_normal_;
  }
  // Box-Muller: u1 in (0, 1] keeps log finite
  const double u1 = 1.0 - uniform_double();
  const double u2 = uniform_double();
  const double radius = std::sqrt(-2.0 * std::log(u1));
  const double angle = kTwoPi * u2;
  spare_normal_ = radius * std::sin(angle);
  has_spare_normal_ = true;
  return radius * std::cos(angle);
}

double PhiloxStream::truncated_normal(double lower, double upper) {
  const double mass =
      0.5 * (std::erfc(-upper / std::sqrt(2.0)) - std::erfc(-lower / std::sqrt(2.0)));
  if (!(lower < upper) || !(mass >= 0.01)) {
    throw std::invalid_argument("PhiloxStream::truncated_normal: [" + std::to_string(lower) + ", " +
                                std::to_string(upper) +
                                "] must be an interval holding >= 1% of N(0, 1)'s mass");
  }
  while (true) {
    const double x = normal();
    if (x >= lower && x <= upper)
      return x;
  }
}

}  // namespace ropes::core
