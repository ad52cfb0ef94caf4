// An allocator for large buffers that are written before they are read (a scan's cells, the
// packets a batcher holds): resize() does not zero-fill what it adds, and the large blocks a
// thread frees last are handed out again instead of going back to the system.
//
// A scan is sized for a 300 rpm rotation (a VLP-16 dual-return scan holds 3.3 MB, a VLS-128 one
// 26 MB). Value-initialised, its storage was zeroed and page-faulted whole before the first
// rotation, whatever the rotation filled; and the allocator handed the pages of a closed reader
// back to the system, so that the next reader (a tool or a test going through captures, a
// replay restarted) faulted them in again: most of the time a short capture took from the file
// (docs/driver.md, "Side by side with velodyne_decoder").
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <new>
#include <type_traits>
#include <utility>

namespace lidartag {

namespace detail {

// The large blocks this thread freed last, handed out again for requests of the same size (the
// fields of a scan of the same shape, the slots of a batcher for the same sensor). At most
// kBlocks blocks and kMaxBytes bytes; the oldest gives way to the newest; freed when the thread
// ends. Plain data, so that it outlives every object of the thread: a buffer freed after the
// thread's cleanup (a static one, destroyed at exit) goes back to the heap as usual.
struct BlockCache {
  static constexpr size_t kMinBytes = size_t{16} << 10;  // smaller blocks are left to the heap
  static constexpr size_t kMaxBytes = size_t{64} << 20;  // a dual-return VLS-128 scan is 26 MB
  static constexpr size_t kBlocks = 12;  // a scan's eight cell fields and a batcher's packets

  struct Block {
    void* p;
    size_t bytes;
  };
  std::array<Block, kBlocks> blocks;
  size_t held_bytes;
  size_t next;  // the slot to give way next
  bool closed;  // the thread's cleanup ran: nothing more is kept

  void* take(size_t bytes) noexcept {
    for (Block& b : blocks) {
      if (b.p != nullptr && b.bytes == bytes) {
        void* p = b.p;
        b.p = nullptr;
        held_bytes -= bytes;
        return p;
      }
    }
    return nullptr;
  }
  bool keep(void* p, size_t bytes) noexcept {
    if (closed || bytes < kMinBytes || bytes > kMaxBytes) return false;
    for (size_t tries = 0; tries <= kBlocks; ++tries) {
      Block* free_slot = nullptr;
      for (Block& b : blocks)
        if (b.p == nullptr) free_slot = &b;
      if (free_slot != nullptr && held_bytes + bytes <= kMaxBytes) {
        *free_slot = {p, bytes};
        held_bytes += bytes;
        return true;
      }
      give_way();
    }
    return false;
  }
  void give_way() noexcept {
    Block& b = blocks[next];
    next = (next + 1) % kBlocks;
    if (b.p == nullptr) return;
    ::operator delete(b.p);
    held_bytes -= b.bytes;
    b.p = nullptr;
  }
  void release() noexcept {
    for (size_t i = 0; i < kBlocks; ++i) give_way();
    closed = true;
  }
};
static_assert(std::is_trivially_destructible_v<BlockCache>);

// This thread's cache; its blocks are freed when the thread ends.
inline BlockCache& block_cache() noexcept {
  thread_local BlockCache cache{};
  struct Cleanup {
    ~Cleanup() { cache.release(); }
  };
  thread_local Cleanup cleanup;
  (void)cleanup;
  return cache;
}

}  // namespace detail

// std::allocator whose resize() leaves new elements default-initialised (a scalar: whatever the
// memory held, no page touched), and whose large blocks go through the thread's block cache.
template <class T>
struct ReusingAllocator : std::allocator<T> {
  template <class U>
  struct rebind {
    using other = ReusingAllocator<U>;
  };
  ReusingAllocator() = default;
  template <class U>
  ReusingAllocator(const ReusingAllocator<U>&) noexcept {}

  T* allocate(size_t n) {
    if (n <= SIZE_MAX / sizeof(T)) {
      if (void* p = detail::block_cache().take(n * sizeof(T))) return static_cast<T*>(p);
    }
    return std::allocator<T>::allocate(n);
  }
  void deallocate(T* p, size_t n) noexcept {
    if (detail::block_cache().keep(p, n * sizeof(T))) return;
    std::allocator<T>::deallocate(p, n);
  }
  template <class U>
  void construct(U* p) noexcept(std::is_nothrow_default_constructible_v<U>) {
    ::new (static_cast<void*>(p)) U;  // default-initialised
  }
  template <class U, class... Args>
  void construct(U* p, Args&&... args) {
    ::new (static_cast<void*>(p)) U(std::forward<Args>(args)...);
  }
};

}  // namespace lidartag
