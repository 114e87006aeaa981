#pragma once
// Heap allocations of the test process are counted while g_heap.counting is set (for tests that
// check that real-time calls do not allocate). Include in one translation unit of a test only:
// it replaces the global operator new and delete.
#include <algorithm>
#include <atomic>
#include <cstdlib>
#include <new>

namespace {
struct HeapCounter {
  std::atomic<bool> counting{false};
  std::atomic<long> allocations{0};
};
HeapCounter g_heap;
}  // namespace

[[gnu::noinline]] void* operator new(std::size_t size) {
  if (g_heap.counting.load(std::memory_order_relaxed))
    g_heap.allocations.fetch_add(1, std::memory_order_relaxed);
  void* block = std::malloc(std::max<std::size_t>(size, 1));
  if (block == nullptr) throw std::bad_alloc();
  return block;
}
[[gnu::noinline]] void operator delete(void* block) noexcept { std::free(block); }
[[gnu::noinline]] void operator delete(void* block, std::size_t) noexcept { std::free(block); }
