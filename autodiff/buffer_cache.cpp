#include "autodiff/buffer_cache.h"

#include <sys/mman.h>

#include <cstdlib>
#include <map>
#include <mutex>
#include <string>

namespace sl {
namespace {

constexpr size_t kHugePage = size_t{2} << 20;

size_t limit_from_environment() {
  const char* env = std::getenv("STREETLIGHT_BUFFER_CACHE_MB");
  if (!env || !*env) return size_t{1} << 30;
  char* end = nullptr;
  const long long mb = std::strtoll(env, &end, 10);
  if (*end != '\0' || mb < 0) return size_t{1} << 30;  // unreadable: keep the default
  return static_cast<size_t>(mb) << 20;
}

struct Cache {
  std::mutex mutex;
  std::multimap<size_t, void*> free_blocks;  // capacity -> block
  size_t cached = 0;
  int64_t hits = 0, misses = 0;
  const size_t limit = limit_from_environment();
};

Cache& cache() {
  static Cache* c = new Cache;  // never destroyed: tensors may outlive static destruction
  return *c;
}

void* allocate_large(size_t capacity) {
  void* p = std::aligned_alloc(kHugePage, capacity);
  if (p) madvise(p, capacity, MADV_HUGEPAGE);  // advisory: failure only costs speed
  return p;
}

}  // namespace

Buffer acquire_buffer(size_t bytes) {
  if (bytes < kMinCachedBytes) {
    const size_t rounded = ((bytes + 63) / 64) * 64;
    return {std::aligned_alloc(64, rounded == 0 ? 64 : rounded), rounded};
  }
  const size_t capacity = (bytes + kHugePage - 1) / kHugePage * kHugePage;
  Cache& c = cache();
  {
    std::lock_guard<std::mutex> lock(c.mutex);
    auto it = c.free_blocks.lower_bound(capacity);
    if (it != c.free_blocks.end() && it->first <= capacity + capacity / 4) {
      const Buffer b{it->second, it->first};
      c.cached -= it->first;
      c.free_blocks.erase(it);
      ++c.hits;
      return b;
    }
    ++c.misses;
  }
  void* p = allocate_large(capacity);
  if (!p) {
    buffer_cache_clear();
    p = allocate_large(capacity);
  }
  return {p, capacity};
}

void release_buffer(Buffer b) {
  if (!b.data) return;
  if (b.capacity >= kMinCachedBytes) {
    Cache& c = cache();
    std::lock_guard<std::mutex> lock(c.mutex);
    if (c.cached + b.capacity <= c.limit) {
      c.free_blocks.emplace(b.capacity, b.data);
      c.cached += b.capacity;
      return;
    }
  }
  std::free(b.data);
}

BufferCacheStats buffer_cache_stats() {
  Cache& c = cache();
  std::lock_guard<std::mutex> lock(c.mutex);
  return {c.hits, c.misses, static_cast<int64_t>(c.cached)};
}

size_t buffer_cache_limit_bytes() { return cache().limit; }

int64_t buffer_cache_clear() {
  Cache& c = cache();
  std::lock_guard<std::mutex> lock(c.mutex);
  const int64_t freed = static_cast<int64_t>(c.cached);
  for (auto& [cap, p] : c.free_blocks) std::free(p);
  c.free_blocks.clear();
  c.cached = 0;
  return freed;
}

}  // namespace sl
