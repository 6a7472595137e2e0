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
// what `c.noalias() = a * b` runs for a row-major destination and row-major operands
using Kernel =
    Eigen::internal::general_matrix_matrix_product<Index, float, Eigen::RowMajor, false, float,
                                                   Eigen::RowMajor, false, Eigen::RowMajor, 1>;

// Eigen's blocking sizes for the whole m x k x n product (what its serial path computes),
// with the packing blocks pointed at this thread's workspace instead of the heap
class WorkspaceBlocking : public EigenBlocking {
 public:
  WorkspaceBlocking(Index m, Index n, Index k) : EigenBlocking(m, n, k, 1, true) {
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

// rows [begin, end) of c = a * b
void rows_of_product(const float* a, const float* b, float* c, Index m, Index k, Index n,
                     Index begin, Index end) {
  WorkspaceBlocking blocking(m, n, k);
  std::fill(c + begin * n, c + end * n, 0.0f);
  Kernel::run(end - begin, n, k, a + begin * k, k, b, n, c + begin * n, 1, n, 1.0f, blocking);
}

// rows go to threads in whole multiples of this (a multiple of every register panel width
// of Eigen's kernel), so that a row's arithmetic does not depend on the split
constexpr Index kRowQuantum = 16;
// Eigen's own threshold: no thread for less than this many multiply-adds
constexpr double kMinWorkPerThread = 50000;

}  // namespace

void gemm(const float* a, const float* b, float* c, std::int64_t m, std::int64_t k,
          std::int64_t n) {
  if (m == 0 || n == 0)
    return;
  if (k == 0) {
    std::fill(c, c + m * n, 0.0f);
    return;
  }
  const Eigen::Map<const RowMajor> am(a, m, k), bm(b, k, n);
  Eigen::Map<RowMajor> cm(c, m, n);
  // Eigen's own dispatch: coefficient-wise for tiny products, GEMV for vectors (neither
  // allocates for contiguous operands)
  if (m == 1 || n == 1 || k + m + n < EIGEN_GEMM_TO_COEFFBASED_THRESHOLD) {
    cm.noalias() = am * bm;
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
    rows_of_product(a, b, c, m, k, n, 0, m);
    return;
  }
  parallel_for(quanta, static_cast<int>(chunks), [&](int, std::int64_t begin, std::int64_t end) {
    rows_of_product(a, b, c, m, k, n, begin * kRowQuantum, std::min(end * kRowQuantum, m));
  });
}

}  // namespace ropes::nn
