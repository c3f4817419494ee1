#include "util/process_memory.h"

#include <cstdlib>
#include <cstring>
#include <vector>

#include <gtest/gtest.h>

#include "tests/support/address_sanitizer.h"

namespace sl {
namespace {

constexpr int64_t kMiB = int64_t{1} << 20;

TEST(ProcessMemory, ResidentBytesFollowsTouchedMemory) {
  const int64_t before = resident_bytes();
  ASSERT_GT(before, 0);
  // 256 MiB written through: resident grows by about that much.
  std::vector<char> block(size_t(256 * kMiB));
  std::memset(block.data(), 1, block.size());
  EXPECT_GT(resident_bytes() - before, 200 * kMiB);
  EXPECT_EQ(block[12345], 1);
}

TEST(ProcessMemory, ReleaseFreeHeapGivesBackPagesHeldBetweenLiveBlocks) {
#if !defined(__GLIBC__)
  GTEST_SKIP() << "release_free_heap does nothing without glibc";
#elif defined(STREETLIGHT_ADDRESS_SANITIZER)
  GTEST_SKIP() << "a sanitizer's allocator holds the heap, not glibc's";
#else
  // 2000 blocks of 96 KiB (below malloc's mmap threshold, so on the heap), each followed by a small
  // block kept alive: freeing the large ones leaves ~190 MiB of free pages that free() alone does
  // not return, because live blocks sit between them and at the heap's top.
  constexpr int kBlocks = 2000;
  constexpr size_t kLarge = 96 * 1024;
  std::vector<char*> large(kBlocks), small(kBlocks);
  for (int i = 0; i < kBlocks; ++i) {
    large[size_t(i)] = static_cast<char*>(std::malloc(kLarge));
    small[size_t(i)] = static_cast<char*>(std::malloc(64));
    ASSERT_TRUE(large[size_t(i)] && small[size_t(i)]);
    std::memset(large[size_t(i)], 1, kLarge);
    small[size_t(i)][0] = char(i);
  }
  for (char* p : large) std::free(p);
  const int64_t held = resident_bytes();
  release_free_heap();
  const int64_t after = resident_bytes();
  EXPECT_GT(held - after, 100 * kMiB) << "held " << held << " bytes, " << after << " after release_free_heap";
  // The live blocks are untouched.
  for (int i = 0; i < kBlocks; ++i) EXPECT_EQ(small[size_t(i)][0], char(i));
  for (char* p : small) std::free(p);
#endif
}

}  // namespace
}  // namespace sl
