// The kernels' matrix product (src/gemm.hpp): the blocking is Eigen's heuristic at fixed
// cache sizes, so the bits do not depend on what the CPU reports nor on the thread count.
#include "gemm.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <vector>

#include "ropes_core/philox.hpp"
#include "ropes_nn/parallel.hpp"

namespace ropes::nn {
namespace {

// a machine with a 32 KiB L1 and a 256 KiB L2 (an older x86-64 core), as Eigen would query it
constexpr CacheSizes kOtherCpu{32768, 262144, 8388608};

std::vector<float> gemm_normals(std::size_t n, std::uint64_t seed) {
  core::PhiloxStream rng(seed, 0);
  std::vector<float> v(n);
  for (float& x : v)
    x = static_cast<float>(rng.normal());
  return v;
}

struct Shape3 {
  std::int64_t m, k, n;
};
// the convolutions' products (o x patch x pixels and their adjoints), a square one, and
// depths long enough that Eigen splits the sum over k at some cache size; the last three
// have fewer rows than a thread's share (one image's convolution: 8 or 16 channels, 9 to 144
// deep, up to 128x128 pixels), so the threads split their columns
const Shape3 kShapes[] = {{16, 16, 1024},  {64, 288, 256},  {47, 576, 81},   {128, 1152, 64},
                          {96, 3000, 40},  {33, 5000, 130}, {300, 700, 300}, {8, 72, 16384},
                          {16, 144, 4099}, {8, 9, 5000}};

// The witness is Eigen's own computeProductBlockingSizes, called with its cache sizes set to
// the same values: reference_blocking must be the same arithmetic, at the reference and at
// another CPU's sizes (for the kernels this CPU runs; ROPES_ISA=v3 checks the v3 copy).
TEST(Gemm, ReferenceBlockingIsEigensHeuristicAtFixedCacheSizes) {
  for (const CacheSizes& caches : {kReferenceCaches, kOtherCpu}) {
    for (std::int64_t k : {1, 8, 47, 48, 200, 576, 1152, 3000, 20000}) {
      for (std::int64_t m : {1, 16, 47, 48, 300, 4096}) {
        for (std::int64_t n : {1, 4, 47, 64, 1000, 16384}) {
          std::int64_t k1 = k, m1 = m, n1 = n, k2 = k, m2 = m, n2 = n;
          reference_blocking(k1, m1, n1, caches);
          eigen_blocking_at(caches, k2, m2, n2);
          EXPECT_EQ(k1, k2) << "k " << k << " m " << m << " n " << n << " l1 " << caches.l1;
          EXPECT_EQ(m1, m2) << "k " << k << " m " << m << " n " << n << " l1 " << caches.l1;
          EXPECT_EQ(n1, n2) << "k " << k << " m " << m << " n " << n << " l1 " << caches.l1;
        }
      }
    }
  }
  // and the two machines do block differently: the fixed sizes are what keeps the bits
  std::int64_t k1 = 3000, m1 = 40, n1 = 96, k2 = 3000, m2 = 40, n2 = 96;
  reference_blocking(k1, m1, n1);
  reference_blocking(k2, m2, n2, kOtherCpu);
  EXPECT_NE(k1, k2);
}

// op(a) op(b) for the four transpose combinations, against a double-precision product
// (the witness), with and without accumulation into c, on 1 and 3 threads (3 splits the rows,
// so every row offset of a transposed operand is used)
TEST(Gemm, TransposedAndAccumulatedProductsAreTheProduct) {
  const int saved = num_threads();
  for (const Shape3& s : kShapes) {
    const std::vector<float> a = gemm_normals(static_cast<std::size_t>(s.m * s.k), 1);
    const std::vector<float> b = gemm_normals(static_cast<std::size_t>(s.k * s.n), 2);
    const std::vector<float> c0 = gemm_normals(static_cast<std::size_t>(s.m * s.n), 3);
    // the transposed copies, stored [k, m] and [n, k]
    std::vector<float> at(a.size()), bt(b.size());
    for (std::int64_t i = 0; i < s.m; ++i)
      for (std::int64_t j = 0; j < s.k; ++j)
        at[static_cast<std::size_t>(j * s.m + i)] = a[static_cast<std::size_t>(i * s.k + j)];
    for (std::int64_t i = 0; i < s.k; ++i)
      for (std::int64_t j = 0; j < s.n; ++j)
        bt[static_cast<std::size_t>(j * s.k + i)] = b[static_cast<std::size_t>(i * s.n + j)];
    std::vector<double> want(static_cast<std::size_t>(s.m * s.n), 0.0);
    for (std::int64_t i = 0; i < s.m; ++i)
      for (std::int64_t p = 0; p < s.k; ++p)
        for (std::int64_t j = 0; j < s.n; ++j)
          want[static_cast<std::size_t>(i * s.n + j)] +=
              static_cast<double>(a[static_cast<std::size_t>(i * s.k + p)]) *
              b[static_cast<std::size_t>(p * s.n + j)];
    const double tolerance = 1e-5 * std::sqrt(static_cast<double>(s.k)) * 4;
    for (int threads : {1, 3}) {
      set_num_threads(threads);
      for (int combination = 0; combination < 4; ++combination) {
        const bool ta = combination & 1, tb = combination & 2;
        for (bool accumulate : {false, true}) {
          std::vector<float> c = c0;
          gemm(ta ? at.data() : a.data(), ta, tb ? bt.data() : b.data(), tb, c.data(), s.m, s.k,
               s.n, accumulate);
          for (std::size_t i = 0; i < c.size(); ++i) {
            const double expected = want[i] + (accumulate ? c0[i] : 0.0);
            ASSERT_NEAR(c[i], expected, tolerance * (1 + std::abs(expected)))
                << s.m << "x" << s.k << "x" << s.n << " transposes " << ta << tb << " accumulate "
                << accumulate << " threads " << threads << " at " << i;
          }
        }
      }
    }
  }
  set_num_threads(saved);
}

// every transpose combination, with and without accumulation, at `threads`
std::vector<float> products_at(const Shape3& s, int threads) {
  set_num_threads(threads);
  const std::vector<float> a = gemm_normals(static_cast<std::size_t>(s.m * s.k), 4);
  const std::vector<float> b = gemm_normals(static_cast<std::size_t>(s.k * s.n), 5);
  const std::vector<float> c0 = gemm_normals(static_cast<std::size_t>(s.m * s.n), 6);
  std::vector<float> all;
  for (int combination = 0; combination < 4; ++combination) {
    for (bool accumulate : {false, true}) {
      std::vector<float> c = c0;
      gemm(a.data(), combination & 1, b.data(), combination & 2, c.data(), s.m, s.k, s.n,
           accumulate);
      all.insert(all.end(), c.begin(), c.end());
    }
  }
  return all;
}

// What another CPU would change: the cache sizes Eigen queries (set here, in the selected
// kernels' own Eigen, as that CPU would report them) and the thread count. Neither may change
// a bit.
TEST(Gemm, SameBitsWhateverTheCpuReportsAndAtEveryThreadCount) {
  const int saved = num_threads();
  for (const Shape3& s : kShapes) {
    gemm_kernels().set_eigen_caches(kReferenceCaches);
    const std::vector<float> reference = products_at(s, 1);
    gemm_kernels().set_eigen_caches(kOtherCpu);
    const std::string what =
        std::to_string(s.m) + "x" + std::to_string(s.k) + "x" + std::to_string(s.n);
    EXPECT_EQ(products_at(s, 1), reference) << what << " at another CPU's cache sizes";
    EXPECT_EQ(products_at(s, 2), reference) << what << " at 2 threads";
    EXPECT_EQ(products_at(s, 3), reference) << what << " at 3 threads";
  }
  // the kernels' blocking ignores Eigen's setting: leave it at the reference
  gemm_kernels().set_eigen_caches(kReferenceCaches);
  set_num_threads(saved);
}

}  // namespace
}  // namespace ropes::nn
