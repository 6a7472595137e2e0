#pragma once
/// @file buffer.hpp
/// Buffer: the float storage of tensors, drawn from a process-wide caching pool.
///
/// Why: a training step allocates the same activation sizes every step. From glibc, large
/// blocks go back to the OS on free and every fresh page then costs a page fault on first
/// touch (~20 us per 4 KiB here), which made training several times slower. The pool keeps
/// freed blocks by size and hands them out again; elements are not zero-initialised.

#include <cstddef>
#include <cstdint>
#include <new>
#include <vector>

namespace ropes::nn {

namespace pool {
/// A block of at least `bytes` bytes (64-byte aligned), reused from the pool when possible.
void* allocate(std::size_t bytes);
/// Returns a block from allocate() (same `bytes`) to the pool.
void deallocate(void* p, std::size_t bytes) noexcept;
/// Bytes currently held by the pool's free lists, and the cap beyond which freed blocks go
/// back to the system (default 4 GiB; ROPES_POOL_MAX_BYTES in the environment changes it).
std::size_t cached_bytes();
/// Frees every cached block.
void release_cached();
}  // namespace pool

/// A std::allocator-compatible allocator over the pool whose construct() default-initialises
/// (no zeroing of floats that are about to be overwritten).
template <typename T>
struct PoolAllocator {
  using value_type = T;
  PoolAllocator() noexcept = default;
  template <typename U>
  PoolAllocator(const PoolAllocator<U>&) noexcept {}  // NOLINT(google-explicit-constructor)
  T* allocate(std::size_t n) { return static_cast<T*>(pool::allocate(n * sizeof(T))); }
  void deallocate(T* p, std::size_t n) noexcept { pool::deallocate(p, n * sizeof(T)); }
  template <typename U>
  void construct(U* p) noexcept {
    ::new (static_cast<void*>(p)) U;
  }
  template <typename U, typename... Args>
  void construct(U* p, Args&&... args) {
    ::new (static_cast<void*>(p)) U(std::forward<Args>(args)...);
  }
  template <typename U>
  bool operator==(const PoolAllocator<U>&) const noexcept {
    return true;
  }
  template <typename U>
  bool operator!=(const PoolAllocator<U>&) const noexcept {
    return false;
  }
};

/// Tensor storage: a vector of floats from the pool. Buffer(n) leaves the values
/// uninitialised; Buffer(n, value) fills them.
using Buffer = std::vector<float, PoolAllocator<float>>;

}  // namespace ropes::nn
