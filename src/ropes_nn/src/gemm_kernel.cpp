// The instruction-set-specific half of the kernels' GEMM (see gemm_kernel.hpp). Compiled once
// per level with ROPES_KERNEL_NS naming the level's namespace and Eigen renamed.
#include "gemm_kernel.hpp"

#include <Eigen/Core>
#if defined(__AVX512F__)
#include <immintrin.h>
#endif

#ifndef ROPES_KERNEL_NS
#error "compile gemm_kernel.cpp with -DROPES_KERNEL_NS=kernel_<level>"
#endif

// the level this compilation targets, from the compiler's own macros
#if defined(__x86_64__)
#if defined(__AVX512F__) && defined(__AVX512BW__) && defined(__AVX512CD__) && \
    defined(__AVX512DQ__) && defined(__AVX512VL__)
#define ROPES_KERNEL_ISA "x86-64-v4"
#elif defined(__AVX2__) && defined(__FMA__) && defined(__BMI2__) && defined(__F16C__)
#define ROPES_KERNEL_ISA "x86-64-v3"
#elif defined(__SSE4_2__) && defined(__POPCNT__) && defined(__SSSE3__)
#define ROPES_KERNEL_ISA "x86-64-v2"
#else
#define ROPES_KERNEL_ISA "x86-64"
#endif
#else
#define ROPES_KERNEL_ISA "other"
#endif
#if defined(ROPES_KERNEL_NATIVE)
#define ROPES_KERNEL_LEVEL ROPES_KERNEL_ISA " (-march=native)"
#else
#define ROPES_KERNEL_LEVEL ROPES_KERNEL_ISA
#endif

namespace ropes::nn::ROPES_KERNEL_NS {

namespace {

using Index = Eigen::Index;
using RowMajor = Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
using EigenBlocking =
    Eigen::internal::gemm_blocking_space<Eigen::RowMajor, float, float, Eigen::Dynamic,
                                         Eigen::Dynamic, Eigen::Dynamic>;
// what `c.noalias() += op(a) * op(b)` runs for a row-major destination; a transposed
// row-major operand is a column-major one
template <int LhsOrder, int RhsOrder>
using Kernel = Eigen::internal::general_matrix_matrix_product<Index, float, LhsOrder, false, float,
                                                              RhsOrder, false, Eigen::RowMajor, 1>;

// the product's own blocking and packing blocks in place of Eigen's
class GivenBlocking : public EigenBlocking {
 public:
  explicit GivenBlocking(const GemmProduct& p) : EigenBlocking(p.m, p.n, p.k, 1, true) {
    this->m_kc = p.kc;
    this->m_mc = p.mc;
    this->m_nc = p.nc;
    this->m_blockA = p.block_a;
    this->m_blockB = p.block_b;
  }
  ~GivenBlocking() {
    // the blocks belong to the caller: keep Eigen's destructor from freeing them
    this->m_blockA = nullptr;
    this->m_blockB = nullptr;
  }
  GivenBlocking(const GivenBlocking&) = delete;
  GivenBlocking& operator=(const GivenBlocking&) = delete;
};

template <int LhsOrder, int RhsOrder>
void run_block(const GemmProduct& p, Index r0, Index r1, Index c0, Index c1) {
  GivenBlocking blocking(p);
  if (!p.accumulate) {
    for (Index r = r0; r < r1; ++r)
      for (float* c = p.c + r * p.ldc + c0; c != p.c + r * p.ldc + c1; ++c)
        *c = 0.0f;
  }
  // row r0 of op(a): a row of a [m, k], or a column of a [k, m]; column c0 of op(b): a column
  // of b [k, n], or a row of b [n, k]
  const float* lhs = LhsOrder == Eigen::RowMajor ? p.a + r0 * p.lda : p.a + r0;
  const float* rhs = RhsOrder == Eigen::RowMajor ? p.b + c0 : p.b + c0 * p.ldb;
  Kernel<LhsOrder, RhsOrder>::run(r1 - r0, c1 - c0, p.k, lhs, p.lda, rhs, p.ldb,
                                  p.c + r0 * p.ldc + c0, 1, p.ldc, 1.0f, blocking);
}

void block(const GemmProduct& p, std::int64_t r0, std::int64_t r1, std::int64_t c0,
           std::int64_t c1) {
  constexpr int kRow = Eigen::RowMajor, kCol = Eigen::ColMajor;
  if (!p.a_transposed && !p.b_transposed)
    run_block<kRow, kRow>(p, r0, r1, c0, c1);
  else if (!p.a_transposed)
    run_block<kRow, kCol>(p, r0, r1, c0, c1);
  else if (!p.b_transposed)
    run_block<kCol, kRow>(p, r0, r1, c0, c1);
  else
    run_block<kCol, kCol>(p, r0, r1, c0, c1);
}

// What Kernel<LhsOrder, kRow>::run does for a product whose sum over k fits one kc block
// (Eigen/src/Core/products/GeneralMatrixMatrix.h, the sequential loop with one k2 block: for
// each mc block of its rows pack_lhs, then gebp against each nc block of op(a)), with the nc
// blocks of op(a) packed apart, one after another. Row-major c = op(a) b is Eigen's
// column-major c^T = b^T op(a)^T: its lhs is b, its rhs op(a).
template <int LhsOrder>
struct PackedA {
  static constexpr int kRhsOrder = LhsOrder == Eigen::RowMajor ? Eigen::ColMajor : Eigen::RowMajor;
  using Traits = Eigen::internal::gebp_traits<float, float>;
  using LhsMapper = Eigen::internal::const_blas_data_mapper<float, Index, Eigen::ColMajor>;
  using RhsMapper = Eigen::internal::const_blas_data_mapper<float, Index, kRhsOrder>;
  using ResMapper =
      Eigen::internal::blas_data_mapper<float, Index, Eigen::ColMajor, Eigen::Unaligned, 1>;

  static bool fits(const GemmProduct& p) { return p.k <= p.kc; }
  static Index nc(const GemmProduct& p) { return p.m < p.nc ? p.m : p.nc; }

  // op(a)'s nc blocks at block_b + j2 * k (k * m floats in all)
  static void pack(const GemmProduct& p) {
    Eigen::internal::gemm_pack_rhs<float, Index, RhsMapper, Traits::nr, kRhsOrder> pack_rhs;
    const RhsMapper rhs(p.a, p.lda);
    for (Index j2 = 0; j2 < p.m; j2 += nc(p))
      pack_rhs(p.block_b + j2 * p.k, rhs.getSubMapper(0, j2), p.k,
               (j2 + nc(p) < p.m ? j2 + nc(p) : p.m) - j2);
  }

  static void run(const GemmProduct& p) {
    Eigen::internal::gemm_pack_lhs<float, Index, LhsMapper, Traits::mr, Traits::LhsProgress,
                                   typename Traits::LhsPacket4Packing, Eigen::ColMajor>
        pack_lhs;
    Eigen::internal::gebp_kernel<float, float, Index, ResMapper, Traits::mr, Traits::nr, false,
                                 false>
        gebp;
    if (!p.accumulate) {
      for (Index r = 0; r < p.m; ++r)
        for (float* c = p.c + r * p.ldc; c != p.c + r * p.ldc + p.n; ++c)
          *c = 0.0f;
    }
    const LhsMapper lhs(p.b, p.ldb);
    const ResMapper res(p.c, p.ldc, 1);
    const Index mc = p.n < p.mc ? p.n : p.mc;
    for (Index i2 = 0; i2 < p.n; i2 += mc) {
      const Index actual_mc = (i2 + mc < p.n ? i2 + mc : p.n) - i2;
      pack_lhs(p.block_a, lhs.getSubMapper(i2, 0), p.k, actual_mc);
      for (Index j2 = 0; j2 < p.m; j2 += nc(p))
        gebp(res.getSubMapper(i2, j2), p.block_a, p.block_b + j2 * p.k, actual_mc, p.k,
             (j2 + nc(p) < p.m ? j2 + nc(p) : p.m) - j2, 1.0f);
    }
  }
};

bool pack_a(const GemmProduct& p) {
  if (p.a_transposed ? !PackedA<Eigen::ColMajor>::fits(p) : !PackedA<Eigen::RowMajor>::fits(p))
    return false;
  if (p.a_transposed)
    PackedA<Eigen::ColMajor>::pack(p);
  else
    PackedA<Eigen::RowMajor>::pack(p);
  return true;
}

void with_packed_a(const GemmProduct& p) {
  if (p.a_transposed)
    PackedA<Eigen::ColMajor>::run(p);
  else
    PackedA<Eigen::RowMajor>::run(p);
}

#if defined(__AVX512F__)
// The forward product of one tile of a stride-1 convolution without its im2col matrix, for the
// v4 kernels: y (+)= w [o, K] * col [K, n], K = c * kh * kw. What the blocked product does to
// one output element is fixed by where its pixel falls in Eigen's packing of the tile
// (gemm_pack_lhs: panels of 48, then one of 32, then one of 16 pixels) and its channel in
// groups of 4 (gebp_kernel's nr): from zero, one fused multiply-add per k in order, k running
// over (channel, ki, kj); in a 16-pixel panel (lhs_process_one_packet) even k of the first
// K & ~7 into one accumulator and odd k into another, the two added, then the remaining k;
// finally fma(acc, 1, what y held), y held 0 or the bias. Here each k's 16 pixels are one load
// from the image, which the caller has padded (top = left = 0, every window inside it: the
// zeros im2col would write are in the image), each weight a broadcast: the same operations on
// the same values. Covered: output channels a multiple of 4, output rows a multiple of 16
// pixels (a vector never spans two), tiles of whole vectors.
using Vec = __m512;
constexpr Index kLanes = 16;

// KH, KW: the window when known at compile time (3x3), else 0 (t.kh, t.kw)
template <int Vectors, int KH, int KW>
void conv_panel(const ConvTile& t, Index first, Index depth) {
  static_assert(Vectors >= 1 && Vectors <= 3, "gebp's panels are 1 to 3 packets");
  const Index kh = KH > 0 ? KH : t.kh, kw = KW > 0 ? KW : t.kw, plane = t.h * t.w;
  Index window[Vectors];  // each vector's first window's top-left pixel in a channel plane
  for (int v = 0; v < Vectors; ++v) {
    const Index pixel = t.p0 + first + v * kLanes;
    window[v] = pixel / t.ow * t.w + pixel % t.ow;
  }
  const Index peeled = depth & ~Index{7};
  const Vec one = _mm512_set1_ps(1.0f);
  for (Index o4 = 0; o4 < t.o; o4 += 4) {
    const float* w[4];
    for (int j = 0; j < 4; ++j)
      w[j] = t.weights + (o4 + j) * depth;
    Vec acc[Vectors][4], odd[4];
    for (int v = 0; v < Vectors; ++v)
      for (int j = 0; j < 4; ++j)
        acc[v][j] = _mm512_setzero_ps();
    for (int j = 0; j < 4; ++j)
      odd[j] = _mm512_setzero_ps();
    Index k = 0;
    for (Index ch = 0; ch < t.c; ++ch) {
      const float* image = t.x + ch * plane;
      for (Index ki = 0; ki < kh; ++ki)
        for (Index kj = 0; kj < kw; ++kj, ++k) {
          Vec a[Vectors];
          for (int v = 0; v < Vectors; ++v)
            a[v] = _mm512_loadu_ps(image + window[v] + ki * t.w + kj);
          if (Vectors == 1 && k < peeled) {
            Vec* into = (k & 1) != 0 ? odd : acc[0];
            for (int j = 0; j < 4; ++j)
              into[j] = _mm512_fmadd_ps(a[0], _mm512_set1_ps(w[j][k]), into[j]);
            continue;
          }
          if (Vectors == 1 && k == peeled && peeled > 0)
            for (int j = 0; j < 4; ++j)
              acc[0][j] = _mm512_add_ps(acc[0][j], odd[j]);
          for (int j = 0; j < 4; ++j) {
            const Vec b = _mm512_set1_ps(w[j][k]);
            for (int v = 0; v < Vectors; ++v)
              acc[v][j] = _mm512_fmadd_ps(a[v], b, acc[v][j]);
          }
        }
    }
    if (Vectors == 1 && peeled == depth && peeled > 0)
      for (int j = 0; j < 4; ++j)
        acc[0][j] = _mm512_add_ps(acc[0][j], odd[j]);
    for (int j = 0; j < 4; ++j) {
      const Vec held = t.bias != nullptr ? _mm512_set1_ps(t.bias[o4 + j]) : _mm512_setzero_ps();
      float* out = t.y + (o4 + j) * t.pixels + t.p0 + first;
      for (int v = 0; v < Vectors; ++v)
        _mm512_storeu_ps(out + v * kLanes, _mm512_fmadd_ps(acc[v][j], one, held));
    }
  }
}

template <int KH, int KW>
void conv_panels(const ConvTile& t, Index depth) {
  Index first = 0;
  for (; first + 3 * kLanes <= t.n; first += 3 * kLanes)
    conv_panel<3, KH, KW>(t, first, depth);
  if (first + 2 * kLanes <= t.n) {
    conv_panel<2, KH, KW>(t, first, depth);
    first += 2 * kLanes;
  }
  if (first + kLanes <= t.n)
    conv_panel<1, KH, KW>(t, first, depth);
}

bool conv_tile_covers(const ConvTile& t) {
  return t.o % 4 == 0 && t.ow % kLanes == 0 && t.p0 % kLanes == 0 && t.n % kLanes == 0 &&
         t.c * t.kh * t.kw > 0 && t.top == 0 && t.left == 0 && t.ow + t.kw - 1 <= t.w &&
         (t.p0 + t.n - 1) / t.ow + t.kh <= t.h;
}

bool conv_tile(const ConvTile& t) {
  using Traits = Eigen::internal::gebp_traits<float, float>;
  static_assert(Traits::mr == 3 * kLanes && Traits::LhsProgress == kLanes && Traits::nr == 4,
                "the panels conv_panel reproduces");
  if (!conv_tile_covers(t))
    return false;
  const Index depth = t.c * t.kh * t.kw;
  if (t.kh == 3 && t.kw == 3)
    conv_panels<3, 3>(t, depth);
  else
    conv_panels<0, 0>(t, depth);
  return true;
}
#else
bool conv_tile_covers(const ConvTile&) {
  return false;
}

bool conv_tile(const ConvTile&) {
  return false;
}
#endif

template <typename Lhs, typename Rhs>
void small_product(const Lhs& a, const Rhs& b, float* c, Index m, Index n, bool accumulate) {
  Eigen::Map<RowMajor> cm(c, m, n);
  if (accumulate)
    cm.noalias() += a * b;
  else
    cm.noalias() = a * b;
}

void small(const GemmProduct& p) {
  using Map = Eigen::Map<const RowMajor>;
  const Map a(p.a, p.a_transposed ? p.k : p.m, p.a_transposed ? p.m : p.k);
  const Map b(p.b, p.b_transposed ? p.n : p.k, p.b_transposed ? p.k : p.n);
  if (!p.a_transposed && !p.b_transposed)
    small_product(a, b, p.c, p.m, p.n, p.accumulate);
  else if (!p.a_transposed)
    small_product(a, b.transpose(), p.c, p.m, p.n, p.accumulate);
  else if (!p.b_transposed)
    small_product(a.transpose(), b, p.c, p.m, p.n, p.accumulate);
  else
    small_product(a.transpose(), b.transpose(), p.c, p.m, p.n, p.accumulate);
}

std::int64_t smaller(std::int64_t a, std::int64_t b) {
  return a < b ? a : b;
}
std::int64_t larger(std::int64_t a, std::int64_t b) {
  return a < b ? b : a;
}

void blocking(std::int64_t& k, std::int64_t& m, std::int64_t& n, const CacheSizes& caches) {
  // the same arithmetic as Eigen 3.4's evaluateProductBlockingSizesHeuristic for one thread
  // (Eigen/src/Core/products/GeneralBlockPanelKernel.h); the unit test checks it against
  // Eigen's own at the same cache sizes
  using Traits = Eigen::internal::gebp_traits<float, float>;
  constexpr std::int64_t kMr = Traits::mr, kNr = Traits::nr, kScalar = sizeof(float);
  std::int64_t l1 = caches.l1;
  const std::int64_t l2 = caches.l2, l3 = caches.l3;
#ifdef EIGEN_VECTORIZE_AVX512
  l1 *= 4;
#endif
  if (larger(k, larger(m, n)) < 48)
    return;
  constexpr std::int64_t k_peeling = 8, k_div = kMr * kScalar + kNr * kScalar,
                         k_sub = kMr * kNr * kScalar;
  const std::int64_t max_kc = larger(((l1 - k_sub) / k_div) & ~(k_peeling - 1), 1);
  const std::int64_t old_k = k;
  if (k > max_kc) {
    k = (k % max_kc) == 0
            ? max_kc
            : max_kc - k_peeling * ((max_kc - 1 - (k % max_kc)) / (k_peeling * (k / max_kc + 1)));
  }
  constexpr std::int64_t actual_l2 = 1572864;  // Eigen's fixed 1.5 MB
  std::int64_t max_nc;
  const std::int64_t lhs_bytes = m * k * kScalar;
  const std::int64_t remaining_l1 = l1 - k_sub - lhs_bytes;
  if (remaining_l1 >= kNr * kScalar * k)
    max_nc = remaining_l1 / (k * kScalar);
  else
    max_nc = (3 * actual_l2) / (2 * 2 * max_kc * kScalar);
  const std::int64_t nc = smaller(actual_l2 / (2 * k * kScalar), max_nc) & ~(kNr - 1);
  if (n > nc) {
    n = (n % nc) == 0 ? nc : nc - kNr * ((nc - (n % nc)) / (kNr * (n / nc + 1)));
  } else if (old_k == k) {
    const std::int64_t problem_size = k * n * kScalar;
    std::int64_t actual_lm = actual_l2, max_mc = m;
    if (problem_size <= 1024) {
      actual_lm = l1;
    } else if (l3 != 0 && problem_size <= 32768) {
      actual_lm = l2;
      max_mc = smaller(576, max_mc);
    }
    std::int64_t mc = smaller(actual_lm / (3 * k * kScalar), max_mc);
    if (mc > kMr)
      mc -= mc % kMr;
    else if (mc == 0)
      return;
    m = (m % mc) == 0 ? mc : mc - kMr * ((mc - (m % mc)) / (kMr * (m / mc + 1)));
  }
}

void set_eigen_caches(const CacheSizes& caches) {
  Eigen::setCpuCacheSizes(caches.l1, caches.l2, caches.l3);
}

void eigen_blocking(const CacheSizes& caches, std::int64_t& k, std::int64_t& m, std::int64_t& n) {
  std::ptrdiff_t l1 = 0, l2 = 0, l3 = 0;
  Eigen::internal::manage_caching_sizes(Eigen::GetAction, &l1, &l2, &l3);
  Eigen::setCpuCacheSizes(caches.l1, caches.l2, caches.l3);
  Index kk = k, mm = m, nn = n;
  Eigen::internal::computeProductBlockingSizes<float, float, 1>(kk, mm, nn, Index{1});
  Eigen::setCpuCacheSizes(l1, l2, l3);
  k = kk;
  m = mm;
  n = nn;
}

}  // namespace

extern const GemmKernels kGemm;
const GemmKernels kGemm{ROPES_KERNEL_LEVEL, &block, &pack_a,   &with_packed_a,  &conv_tile_covers,
                        &conv_tile,         &small, &blocking, &eigen_blocking, &set_eigen_caches};

}  // namespace ropes::nn::ROPES_KERNEL_NS
