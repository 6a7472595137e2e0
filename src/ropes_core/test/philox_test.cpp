#include "ropes_core/philox.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>

namespace ropes::core {
namespace {

// Witness: Random123's published known-answer vectors for Philox4x32-10 (kat_vectors in the
// Random123 distribution; the third pair is the leading hex digits of pi).
TEST(Philox4x32_10Golden, MatchesRandom123KnownAnswers) {
  EXPECT_EQ(philox4x32_10({0, 0, 0, 0}, {0, 0}),
            (PhiloxCounter{0x6627e8d5u, 0xe169c58du, 0xbc57ac4cu, 0x9b00dbd8u}));
  EXPECT_EQ(philox4x32_10({0xffffffffu, 0xffffffffu, 0xffffffffu, 0xffffffffu},
                          {0xffffffffu, 0xffffffffu}),
            (PhiloxCounter{0x408f276du, 0x41c83b0eu, 0xa20bc7c6u, 0x6d5451fdu}));
  EXPECT_EQ(philox4x32_10({0x243f6a88u, 0x85a308d3u, 0x13198a2eu, 0x03707344u},
                          {0xa4093822u, 0x299f31d0u}),
            (PhiloxCounter{0xd16cfe09u, 0x94fdccebu, 0x5001e420u, 0x24126ea1u}));
}

TEST(PhiloxStream, FollowsTheDocumentedCounterLayout) {
  const std::uint64_t seed = 0x0123456789abcdefull;
  const std::uint64_t stream = 0xfedcba9876543210ull;
  PhiloxStream s(seed, stream);
  const PhiloxKey key = {0x89abcdefu, 0x01234567u};
  for (std::uint32_t block = 0; block < 3; ++block) {
    const PhiloxCounter expected = philox4x32_10({block, 0u, 0x76543210u, 0xfedcba98u}, key);
    for (std::uint32_t word : expected) {
      EXPECT_EQ(s.next_u32(), word) << "block " << block;
    }
  }
  EXPECT_EQ(s.words_drawn(), 12u);
}

TEST(PhiloxStream, SameSeedAndStreamGiveSameNumbersOthersDiffer) {
  PhiloxStream a(42, 7), b(42, 7), other_stream(42, 8), other_seed(43, 7);
  for (int i = 0; i < 100; ++i) {
    const std::uint32_t x = a.next_u32();
    EXPECT_EQ(x, b.next_u32());
    EXPECT_NE(x, other_stream.next_u32());
    EXPECT_NE(x, other_seed.next_u32());
  }
}

TEST(PhiloxStream, UniformsStayInTheHalfOpenUnitInterval) {
  PhiloxStream s(1, 0);
  double sum = 0.0;
  const int n = 200000;
  for (int i = 0; i < n; ++i) {
    const float f = s.uniform_float();
    const double d = s.uniform_double();
    ASSERT_GE(f, 0.0f);
    ASSERT_LT(f, 1.0f);
    ASSERT_GE(d, 0.0);
    ASSERT_LT(d, 1.0);
    sum += d;
  }
  // mean of U(0,1) is 1/2 with standard error sqrt(1/12/n) ~ 6.5e-4; allow 5 standard errors
  EXPECT_NEAR(sum / n, 0.5, 5 * std::sqrt(1.0 / 12.0 / n));
}

TEST(PhiloxStream, NormalHasTheMomentsAndTailMassOfNZeroOne) {
  PhiloxStream s(2024, 3);
  const int n = 400000;
  double sum = 0.0, sum_sq = 0.0, sum_4 = 0.0;
  int beyond_two = 0;
  for (int i = 0; i < n; ++i) {
    const double x = s.normal();
    ASSERT_TRUE(std::isfinite(x));
    sum += x;
    sum_sq += x * x;
    sum_4 += x * x * x * x;
    beyond_two += std::abs(x) > 2.0;
  }
  const double mean = sum / n;
  const double var = sum_sq / n - mean * mean;
  // standard errors: mean 1/sqrt(n), variance sqrt(2/n), fourth moment sqrt(96/n)
  EXPECT_NEAR(mean, 0.0, 5.0 / std::sqrt(n));
  EXPECT_NEAR(var, 1.0, 5.0 * std::sqrt(2.0 / n));
  EXPECT_NEAR(sum_4 / n, 3.0, 5.0 * std::sqrt(96.0 / n));
  // P(|X| > 2) = erfc(2 / sqrt 2) = 0.0455003
  const double p = std::erfc(2.0 / std::sqrt(2.0));
  EXPECT_NEAR(static_cast<double>(beyond_two) / n, p, 5.0 * std::sqrt(p * (1 - p) / n));
}

}  // namespace
}  // namespace ropes::core
