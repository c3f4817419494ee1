// The large-buffer cache behind Storage (autodiff/buffer_cache.h).
#include "autodiff/buffer_cache.h"

#include <gtest/gtest.h>

#include <vector>

#include "autodiff/tensor.h"

namespace sl::test {
namespace {

TEST(BufferCache, LargeBufferIsReusedAfterRelease) {
  buffer_cache_clear();
  const BufferCacheStats before = buffer_cache_stats();
  const Buffer a = acquire_buffer(3 << 20);
  ASSERT_NE(a.data, nullptr);
  EXPECT_GE(a.capacity, size_t{3} << 20);
  EXPECT_EQ(reinterpret_cast<uintptr_t>(a.data) % 64, 0u);
  release_buffer(a);
  EXPECT_EQ(buffer_cache_stats().cached_bytes, static_cast<int64_t>(a.capacity));
  const Buffer b = acquire_buffer((3 << 20) - 100);  // rounds to the same capacity
  EXPECT_EQ(b.data, a.data);
  const BufferCacheStats after = buffer_cache_stats();
  EXPECT_EQ(after.hits - before.hits, 1);
  EXPECT_EQ(after.misses - before.misses, 1);
  EXPECT_EQ(after.cached_bytes, 0);
  release_buffer(b);
  EXPECT_GT(buffer_cache_clear(), 0);
}

TEST(BufferCache, SmallBuffersBypassTheCache) {
  const BufferCacheStats before = buffer_cache_stats();
  const Buffer a = acquire_buffer(1000);
  ASSERT_NE(a.data, nullptr);
  EXPECT_EQ(reinterpret_cast<uintptr_t>(a.data) % 64, 0u);
  release_buffer(a);
  const BufferCacheStats after = buffer_cache_stats();
  EXPECT_EQ(after.hits, before.hits);
  EXPECT_EQ(after.misses, before.misses);
  EXPECT_EQ(after.cached_bytes, before.cached_bytes);
}

TEST(BufferCache, NeverHoldsMoreThanItsLimit) {
  buffer_cache_clear();
  // Untouched blocks cost address space only.
  const size_t block = buffer_cache_limit_bytes() / 4 + (size_t{2} << 20);
  std::vector<Buffer> held;
  for (int i = 0; i < 6; ++i) held.push_back(acquire_buffer(block));
  for (const Buffer& b : held) release_buffer(b);
  EXPECT_LE(buffer_cache_stats().cached_bytes, static_cast<int64_t>(buffer_cache_limit_bytes()));
  buffer_cache_clear();
  EXPECT_EQ(buffer_cache_stats().cached_bytes, 0);
}

TEST(BufferCache, ReusedDirtyBufferStillGivesExactZeros) {
  const int64_t n = 1 << 20;  // 4 MiB: cached
  { Tensor dirty = Tensor::full({n}, 7.0); }
  const int64_t live = Storage::live_bytes();
  const Tensor z = Tensor::zeros({n});
  EXPECT_EQ(Storage::live_bytes() - live, n * 4);
  const float* p = z.data<float>();
  for (int64_t i = 0; i < n; ++i) ASSERT_EQ(p[i], 0.0f) << i;
}

}  // namespace
}  // namespace sl::test
