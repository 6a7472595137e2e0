#pragma once
/// @file allocation_counter.hpp
/// Counts the heap allocations of the whole process (every thread) while counting is on:
/// how a benchmark or a test shows that a warm inference call allocates nothing.
///
/// Every allocation of the process goes through malloc and its siblings (operator new,
/// Eigen's aligned blocks and ropes_nn's buffer pool included); this header defines them,
/// interposing glibc's, and counts the calls. Include it in exactly one source file of an
/// executable — never of a library, never twice (the definitions would clash at link time).
///
/// Under AddressSanitizer the header defines nothing: ASan owns malloc, and an interposer
/// on glibc's allocator would hand ASan blocks it never made. `available` is then false,
/// and a test that needs the count skips (ci/test --sanitize builds that way).
#include <atomic>
#include <cerrno>
#include <cstddef>
#include <cstdint>

extern "C" {
void* __libc_malloc(std::size_t);
void* __libc_calloc(std::size_t, std::size_t);
void* __libc_realloc(void*, std::size_t);
void* __libc_memalign(std::size_t, std::size_t);
void* __libc_valloc(std::size_t);
void* __libc_pvalloc(std::size_t);
void __libc_free(void*);
}

#if defined(__SANITIZE_ADDRESS__)
#define ROPES_ALLOCATION_COUNTER_OFF 1
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
#define ROPES_ALLOCATION_COUNTER_OFF 1
#endif
#endif

namespace ropes::nn::allocation_counter {

/// False in a sanitizer build, where nothing is counted (stop() returns 0).
#if defined(ROPES_ALLOCATION_COUNTER_OFF)
inline constexpr bool available = false;
#else
inline constexpr bool available = true;
#endif

namespace detail {
inline std::atomic<bool> counting{false};
inline std::atomic<std::uint64_t> count{0};
inline void note() {
  if (counting.load(std::memory_order_relaxed))
    count.fetch_add(1, std::memory_order_relaxed);
}
}  // namespace detail

/// Sets the count to zero and starts counting.
inline void start() {
  detail::count = 0;
  detail::counting = true;
}
/// Stops counting; returns the allocations since start().
inline std::uint64_t stop() {
  detail::counting = false;
  return detail::count.load();
}

}  // namespace ropes::nn::allocation_counter

#if !defined(ROPES_ALLOCATION_COUNTER_OFF)
extern "C" {
void* malloc(std::size_t n) noexcept {
  ::ropes::nn::allocation_counter::detail::note();
  return __libc_malloc(n);
}
void* calloc(std::size_t n, std::size_t size) noexcept {
  ::ropes::nn::allocation_counter::detail::note();
  return __libc_calloc(n, size);
}
void* realloc(void* p, std::size_t n) noexcept {
  ::ropes::nn::allocation_counter::detail::note();
  return __libc_realloc(p, n);
}
void* aligned_alloc(std::size_t alignment, std::size_t n) noexcept {
  ::ropes::nn::allocation_counter::detail::note();
  return __libc_memalign(alignment, n);
}
void* memalign(std::size_t alignment, std::size_t n) noexcept {
  ::ropes::nn::allocation_counter::detail::note();
  return __libc_memalign(alignment, n);
}
void* valloc(std::size_t n) noexcept {
  ::ropes::nn::allocation_counter::detail::note();
  return __libc_valloc(n);
}
void* pvalloc(std::size_t n) noexcept {
  ::ropes::nn::allocation_counter::detail::note();
  return __libc_pvalloc(n);
}
void* reallocarray(void* p, std::size_t n, std::size_t size) noexcept {
  ::ropes::nn::allocation_counter::detail::note();
  if (size != 0 && n > static_cast<std::size_t>(-1) / size) {
    errno = ENOMEM;
    return nullptr;
  }
  return __libc_realloc(p, n * size);
}
int posix_memalign(void** out, std::size_t alignment, std::size_t n) noexcept {
  ::ropes::nn::allocation_counter::detail::note();
  if (alignment < sizeof(void*) || (alignment & (alignment - 1)) != 0)
    return EINVAL;
  void* p = __libc_memalign(alignment, n);
  if (p == nullptr)
    return ENOMEM;
  *out = p;
  return 0;
}
void free(void* p) noexcept {
  __libc_free(p);
}
}
#endif  // !ROPES_ALLOCATION_COUNTER_OFF
