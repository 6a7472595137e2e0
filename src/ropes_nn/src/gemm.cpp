#include "gemm.hpp"

#include <omp.h>
#include <Eigen/Core>

#include <algorithm>

#include "ropes_nn/buffer.hpp"
#include "ropes_nn/parallel.hpp"

namespace ropes::nn {

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

// the reference blocking of the whole m x k x n product, with the packing blocks pointed
// at this thread's workspace instead of the heap
class WorkspaceBlocking : public EigenBlocking {
 public:
  WorkspaceBlocking(Index m, Index n, Index k) : EigenBlocking(m, n, k, 1, true) {
    // a row-major product is Eigen's column-major one transposed: mc runs over n, nc over m
    std::int64_t kc = k, mc = n, nc = m;
    reference_blocking(kc, mc, nc);
    this->m_kc = kc;
    this->m_mc = mc;
    this->m_nc = nc;
    thread_local Buffer block_a, block_b;
    // both blocks first: if growing one throws, Eigen's destructor must still see null
    float* a = at_least(block_a, static_cast<std::size_t>(this->m_kc * this->m_mc));
    float* b = at_least(block_b, static_cast<std::size_t>(this->m_kc * this->m_nc));
    this->m_blockA = a;
    this->m_blockB = b;
  }
  ~WorkspaceBlocking() {
    // the blocks belong to the workspace: keep Eigen's destructor from freeing them
    this->m_blockA = nullptr;
    this->m_blockB = nullptr;
  }
  WorkspaceBlocking(const WorkspaceBlocking&) = delete;
  WorkspaceBlocking& operator=(const WorkspaceBlocking&) = delete;

 private:
  static float* at_least(Buffer& buffer, std::size_t size) {
    if (buffer.size() < size)
      buffer = Buffer(size);
    return buffer.data();
  }
};

struct Product {
  const float* a;
  bool a_transposed;
  const float* b;
  bool b_transposed;
  float* c;
  Index m, k, n;
  bool accumulate;
};

template <int LhsOrder, int RhsOrder>
void run_rows(const Product& p, Index begin, Index end) {
  WorkspaceBlocking blocking(p.m, p.n, p.k);
  if (!p.accumulate)
    std::fill(p.c + begin * p.n, p.c + end * p.n, 0.0f);
  // row `begin` of op(a): a row of a [m, k], or a column of a [k, m]
  const float* lhs = LhsOrder == Eigen::RowMajor ? p.a + begin * p.k : p.a + begin;
  const Index lhs_stride = LhsOrder == Eigen::RowMajor ? p.k : p.m;
  const Index rhs_stride = RhsOrder == Eigen::RowMajor ? p.n : p.k;
  Kernel<LhsOrder, RhsOrder>::run(end - begin, p.n, p.k, lhs, lhs_stride, p.b, rhs_stride,
                                  p.c + begin * p.n, 1, p.n, 1.0f, blocking);
}

// rows [begin, end) of the product
void rows_of_product(const Product& p, Index begin, Index end) {
  constexpr int kRow = Eigen::RowMajor, kCol = Eigen::ColMajor;
  if (!p.a_transposed && !p.b_transposed)
    run_rows<kRow, kRow>(p, begin, end);
  else if (!p.a_transposed)
    run_rows<kRow, kCol>(p, begin, end);
  else if (!p.b_transposed)
    run_rows<kCol, kRow>(p, begin, end);
  else
    run_rows<kCol, kCol>(p, begin, end);
}

template <typename Lhs, typename Rhs>
void small_product(const Lhs& a, const Rhs& b, float* c, Index m, Index n, bool accumulate) {
  Eigen::Map<RowMajor> cm(c, m, n);
  if (accumulate)
    cm.noalias() += a * b;
  else
    cm.noalias() = a * b;
}

// Eigen's expression for tiny and vector-shaped products (coefficient-wise or GEMV: neither
// blocks, threads nor allocates for contiguous operands)
void small_product(const Product& p) {
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

// rows go to threads in whole multiples of this (a multiple of every register panel width
// of Eigen's kernel), so that a row's arithmetic does not depend on the split
constexpr Index kRowQuantum = 16;
// Eigen's own threshold: no thread for less than this many multiply-adds
constexpr double kMinWorkPerThread = 50000;

}  // namespace

void reference_blocking(std::int64_t& k, std::int64_t& m, std::int64_t& n,
                        const CacheSizes& caches) {
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
  if (std::max({k, m, n}) < 48)
    return;
  constexpr std::int64_t k_peeling = 8, k_div = kMr * kScalar + kNr * kScalar,
                         k_sub = kMr * kNr * kScalar;
  const std::int64_t max_kc = std::max<std::int64_t>(((l1 - k_sub) / k_div) & ~(k_peeling - 1), 1);
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
  const std::int64_t nc =
      std::min<std::int64_t>(actual_l2 / (2 * k * kScalar), max_nc) & ~(kNr - 1);
  if (n > nc) {
    n = (n % nc) == 0 ? nc : nc - kNr * ((nc - (n % nc)) / (kNr * (n / nc + 1)));
  } else if (old_k == k) {
    const std::int64_t problem_size = k * n * kScalar;
    std::int64_t actual_lm = actual_l2, max_mc = m;
    if (problem_size <= 1024) {
      actual_lm = l1;
    } else if (l3 != 0 && problem_size <= 32768) {
      actual_lm = l2;
      max_mc = std::min<std::int64_t>(576, max_mc);
    }
    std::int64_t mc = std::min<std::int64_t>(actual_lm / (3 * k * kScalar), max_mc);
    if (mc > kMr)
      mc -= mc % kMr;
    else if (mc == 0)
      return;
    m = (m % mc) == 0 ? mc : mc - kMr * ((mc - (m % mc)) / (kMr * (m / mc + 1)));
  }
}

void eigen_blocking_at(const CacheSizes& caches, std::int64_t& k, std::int64_t& m,
                       std::int64_t& n) {
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

void gemm(const float* a, bool a_transposed, const float* b, bool b_transposed, float* c,
          std::int64_t m, std::int64_t k, std::int64_t n, bool accumulate) {
  if (m == 0 || n == 0)
    return;
  if (k == 0) {
    if (!accumulate)
      std::fill(c, c + m * n, 0.0f);
    return;
  }
  const Product p{a, a_transposed, b, b_transposed, c, m, k, n, accumulate};
  // Eigen's own dispatch for tiny and vector-shaped products
  if (m == 1 || n == 1 || k + m + n < EIGEN_GEMM_TO_COEFFBASED_THRESHOLD) {
    small_product(p);
    return;
  }
  const Index quanta = (m + kRowQuantum - 1) / kRowQuantum;
  const double work = static_cast<double>(m) * static_cast<double>(n) * static_cast<double>(k);
  Index chunks = 1;
  if (!omp_in_parallel()) {
    chunks = std::min<Index>(
        {num_threads(), quanta, std::max<Index>(1, static_cast<Index>(work / kMinWorkPerThread))});
  }
  if (chunks == 1) {
    rows_of_product(p, 0, m);
    return;
  }
  parallel_for(quanta, static_cast<int>(chunks), [&](int, std::int64_t begin, std::int64_t end) {
    rows_of_product(p, begin * kRowQuantum, std::min(end * kRowQuantum, m));
  });
}

}  // namespace ropes::nn
