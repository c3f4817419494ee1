#include "tests/fuzz/alloc_counter.h"

#include <malloc.h>

#include <atomic>
#include <cerrno>
#include <cstdint>
#include <cstring>

#include "tests/support/address_sanitizer.h"

#if defined(STREETLIGHT_ADDRESS_SANITIZER)
#define STREETLIGHT_NO_ALLOC_COUNTER 1
#endif

namespace {
std::atomic<int64_t> g_live{0}, g_peak{0}, g_base{0};

void on_alloc(void* p) {
  if (!p) return;
  const int64_t live = g_live.fetch_add(static_cast<int64_t>(malloc_usable_size(p))) +
                       static_cast<int64_t>(malloc_usable_size(p));
  int64_t peak = g_peak.load(std::memory_order_relaxed);
  while (live > peak && !g_peak.compare_exchange_weak(peak, live)) {
  }
}
void on_free(void* p) {
  if (p) g_live.fetch_sub(static_cast<int64_t>(malloc_usable_size(p)));
}
}  // namespace

#ifndef STREETLIGHT_NO_ALLOC_COUNTER
extern "C" {
void* __libc_malloc(size_t);
void __libc_free(void*);
void* __libc_calloc(size_t, size_t);
void* __libc_realloc(void*, size_t);
void* __libc_memalign(size_t, size_t);

void* malloc(size_t n) {
  void* p = __libc_malloc(n);
  on_alloc(p);
  return p;
}
void free(void* p) {
  on_free(p);
  __libc_free(p);
}
void* calloc(size_t n, size_t size) {
  void* p = __libc_calloc(n, size);
  on_alloc(p);
  return p;
}
void* realloc(void* old, size_t n) {
  const int64_t before = old ? static_cast<int64_t>(malloc_usable_size(old)) : 0;
  void* p = __libc_realloc(old, n);
  if (p || n == 0) {
    g_live.fetch_sub(before);
    on_alloc(p);
  }
  return p;
}
void* memalign(size_t alignment, size_t n) {
  void* p = __libc_memalign(alignment, n);
  on_alloc(p);
  return p;
}
void* aligned_alloc(size_t alignment, size_t n) { return memalign(alignment, n); }
int posix_memalign(void** out, size_t alignment, size_t n) {
  if (alignment % sizeof(void*) != 0 || (alignment & (alignment - 1)) != 0) return EINVAL;
  void* p = memalign(alignment, n);
  if (!p && n != 0) return ENOMEM;
  *out = p;
  return 0;
}
void* valloc(size_t n) { return memalign(4096, n); }
void* pvalloc(size_t n) { return memalign(4096, (n + 4095) & ~size_t{4095}); }
}
#endif

namespace sl::test {

bool alloc_counter_available() {
#ifdef STREETLIGHT_NO_ALLOC_COUNTER
  return false;
#else
  return true;
#endif
}

void reset_peak() {
  const int64_t live = g_live.load();
  g_base.store(live);
  g_peak.store(live);
}

size_t peak_since_reset() {
  const int64_t d = g_peak.load() - g_base.load();
  return d > 0 ? static_cast<size_t>(d) : 0;
}

}  // namespace sl::test
