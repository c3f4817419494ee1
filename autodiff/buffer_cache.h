// Large tensor buffers: 2 MiB-aligned, backed by transparent huge pages, and cached after release.
//
// Contract:
// - acquire_buffer(bytes) returns a 64-byte aligned block of at least `bytes` bytes and its
//   capacity; release_buffer(ptr, capacity) gives it back. Contents are unspecified (never
//   assume zeros). Thread-safe.
// - Blocks below kMinCachedBytes come from and go to aligned_alloc unchanged.
// - Larger blocks have a capacity rounded up to 2 MiB, are advised as huge pages
//   (MADV_HUGEPAGE), and on release are kept, up to a total of buffer_cache_limit_bytes()
//   (default 1 GiB; environment STREETLIGHT_BUFFER_CACHE_MB, 0 disables), for the next request
//   whose rounded size they fit within 25%. Training repeats the same shapes every step, so
//   after the first step its large tensors cost no page faults and no kernel zeroing (the cost
//   that dominates memory-bound kernels on 16M-element tensors). If an allocation fails, the
//   cache is emptied and the allocation retried before failing.
#pragma once
#include <cstddef>
#include <cstdint>

namespace sl {

constexpr size_t kMinCachedBytes = size_t{1} << 20;

struct Buffer {
  void* data = nullptr;
  size_t capacity = 0;
};

Buffer acquire_buffer(size_t bytes);
void release_buffer(Buffer buffer);

struct BufferCacheStats {
  int64_t hits = 0;          // large requests served from the cache
  int64_t misses = 0;        // large requests that allocated
  int64_t cached_bytes = 0;  // bytes held by the cache now
};
BufferCacheStats buffer_cache_stats();
size_t buffer_cache_limit_bytes();
// Frees every cached block (returns the bytes freed).
int64_t buffer_cache_clear();

}  // namespace sl
