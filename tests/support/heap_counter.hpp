#pragma once
// Heap allocations of the test process, counted for tests that check that real-time calls do not
// allocate: on every thread while g_heap.counting is set, on the thread g_heap.watched names, and
// on a thread that sets t_heap_counting. Include in one translation unit of a test only: it
// replaces the global operator new and delete.
#include <algorithm>
#include <atomic>
#include <cstdlib>
#include <new>
#include <thread>

namespace {
struct HeapCounter {
  std::atomic<bool> counting{false};
  std::atomic<std::thread::id> watched{};
  std::atomic<long> allocations{0};
};
HeapCounter g_heap;
thread_local bool t_heap_counting = false;
}  // namespace

// The replacements pair malloc with free, out of line so that the compiler does not pair an
// inlined free() with operator new at call sites.
[[gnu::noinline]] void* operator new(std::size_t size) {
  if (g_heap.counting.load(std::memory_order_relaxed) || t_heap_counting ||
      g_heap.watched.load(std::memory_order_relaxed) == std::this_thread::get_id())
    g_heap.allocations.fetch_add(1, std::memory_order_relaxed);
  void* block = std::malloc(std::max<std::size_t>(size, 1));
  if (block == nullptr) throw std::bad_alloc();
  return block;
}
[[gnu::noinline]] void operator delete(void* block) noexcept { std::free(block); }
[[gnu::noinline]] void operator delete(void* block, std::size_t) noexcept { std::free(block); }
