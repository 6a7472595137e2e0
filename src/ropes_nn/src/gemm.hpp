#pragma once
// Private: the matrix product of the convolution kernels, without heap allocation.
#include <cstdint>

namespace ropes::nn {

// c [m, n] = a [m, k] * b [k, n], all row-major and contiguous: the value Eigen's
// `c.noalias() = a * b` computes on one thread, bit for bit, at every thread count.
//
// Why not that expression: for a large product Eigen packs the operands into blocks it takes
// from the heap on every call, which made a warm single-frame inference allocate. Here the
// same kernel (Eigen's general_matrix_matrix_product with the blocking sizes Eigen would
// choose) runs with its blocks from a per-thread workspace that only grows. Outside a
// parallel region the rows of `a` are split over the threads in multiples of 16 (whole
// register panels of the kernel), so each output element is computed by the same
// instructions as on one thread. Small and vector-shaped products go to Eigen's expression,
// which allocates nothing for them.
void gemm(const float* a, const float* b, float* c, std::int64_t m, std::int64_t k, std::int64_t n);

}  // namespace ropes::nn
