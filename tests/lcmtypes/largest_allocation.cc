// The global operator new and delete of the lcmtypes tests: malloc and free underneath, as the library's own (ASan
// and UBSan builds keep intercepting them), with the largest request counted while asked. In a file of its own, so
// no compiler sees these definitions beside the new-expressions that call them.
#include "tests/lcmtypes/largest_allocation.h"

#include <atomic>
#include <cstdlib>
#include <new>

namespace {
std::atomic<bool> g_counting{false};
std::atomic<std::size_t> g_largest{0};
}  // namespace

void* operator new(std::size_t n) {
  if (g_counting.load(std::memory_order_relaxed)) {
    std::size_t seen = g_largest.load(std::memory_order_relaxed);
    while (n > seen && !g_largest.compare_exchange_weak(seen, n)) {
    }
  }
  if (void* p = std::malloc(n == 0 ? 1 : n)) return p;
  throw std::bad_alloc();
}
void* operator new[](std::size_t n) { return ::operator new(n); }
void operator delete(void* p) noexcept { std::free(p); }
void operator delete[](void* p) noexcept { std::free(p); }
void operator delete(void* p, std::size_t) noexcept { std::free(p); }
void operator delete[](void* p, std::size_t) noexcept { std::free(p); }

namespace driftlab::test {

void start_counting_allocations() {
  g_largest = 0;
  g_counting = true;
}

std::size_t largest_allocation() {
  g_counting = false;
  return g_largest.load();
}

}  // namespace driftlab::test
