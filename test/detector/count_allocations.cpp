#include "count_allocations.hpp"

#include <atomic>
#include <cstdlib>
#include <new>

namespace {
std::atomic<long> allocations{0};
std::atomic<long> fail_after{-1};  // allocations left before one fails; -1: never
}  // namespace

// GCC pairs the free() in the replaced operator delete with the library's operator new.
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wmismatched-new-delete"
#endif
void* operator new(std::size_t n) {
  allocations.fetch_add(1, std::memory_order_relaxed);
  if (fail_after.load(std::memory_order_relaxed) >= 0 &&
      fail_after.fetch_sub(1, std::memory_order_relaxed) == 0) {
    fail_after.store(-1, std::memory_order_relaxed);
    throw std::bad_alloc();
  }
  if (void* p = std::malloc(n > 0 ? n : 1)) return p;
  throw std::bad_alloc();
}
void operator delete(void* p) noexcept {
  std::free(p);
}
void operator delete(void* p, std::size_t) noexcept {
  std::free(p);
}
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic pop
#endif

namespace lidartag::testing {

long heap_allocations() {
  return allocations.load(std::memory_order_relaxed);
}

void fail_allocation_after(long n) {
  fail_after.store(n, std::memory_order_relaxed);
}

}  // namespace lidartag::testing
