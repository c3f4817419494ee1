// util/parallel.h: chunk boundaries are a function of (n, grain) alone, every index runs once,
// and short loops are cut into a multiple of 4 chunks so that 2 or 4 threads share them evenly.
#include "util/parallel.h"

#include <gtest/gtest.h>
#include <omp.h>

#include <algorithm>
#include <mutex>
#include <utility>
#include <vector>

namespace sl::test {
namespace {

std::vector<std::pair<int64_t, int64_t>> chunks_of(int64_t n, int64_t grain, int threads) {
  std::vector<std::pair<int64_t, int64_t>> seen;
  std::mutex m;
  const int before = omp_get_max_threads();
  omp_set_num_threads(threads);
  parallel_for(n, grain, [&](int64_t b, int64_t e) {
    std::lock_guard<std::mutex> lock(m);
    seen.emplace_back(b, e);
  });
  omp_set_num_threads(before);
  std::sort(seen.begin(), seen.end());
  return seen;
}

TEST(ParallelFor, FewChunksComeInMultiplesOfFourAndTheBoundariesIgnoreTheThreads) {
  // 8 items at grain 3 were 3 chunks (3, 3, 2): 6 items on one of two threads, 2 on the other.
  EXPECT_EQ(detail::balanced_grain(8, 3), 2);
  EXPECT_EQ(detail::balanced_grain(100, 10), 9);   // 10 chunks -> 12
  EXPECT_EQ(detail::balanced_grain(64, 16), 16);   // already 4 chunks
  EXPECT_EQ(detail::balanced_grain(10, 20), 20);   // one chunk: runs on the caller
  EXPECT_EQ(detail::balanced_grain(330, 10), 10);  // 33 chunks: already even enough
  EXPECT_EQ(detail::balanced_grain(3, 1), 1);      // no shorter chunk exists
  EXPECT_EQ(detail::balanced_grain(6, 2), 1);      // 4 chunks of 2 would be 3: 6 chunks of 1
  for (const auto& [n, grain] : std::vector<std::pair<int64_t, int64_t>>{
           {8, 3}, {100, 10}, {7, 2}, {1000, 37}, {5, 1}, {64, 16}, {1, 1}, {129, 4}, {6, 2}, {30, 4}}) {
    const auto one = chunks_of(n, grain, 1), two = chunks_of(n, grain, 2);
    EXPECT_EQ(one, two) << n << " items at grain " << grain;
    int64_t next = 0;
    for (const auto& [b, e] : two) {
      EXPECT_EQ(b, next) << n << " items at grain " << grain;  // contiguous, no gap, no overlap
      EXPECT_LT(b, e);
      next = e;
    }
    EXPECT_EQ(next, n);
    const int64_t count = static_cast<int64_t>(two.size());
    if (count > 1 && count <= detail::kBalancedChunks && n % 2 == 0) {
      EXPECT_EQ(count % 2, 0) << n << " at " << grain;
    }
  }
}

// SerialLoops (train/inference.cpp): while one lives on this thread, a loop is one call of its
// body on this thread, as inside a parallel region, and the sums are the same bits; after it, the
// loop is chunked again.
TEST(ParallelFor, SerialLoopsRunOnTheCallingThreadWithTheSameSums) {
  const int before = omp_get_max_threads();
  omp_set_num_threads(2);
  const auto f = [](int64_t i) { return 1.0 / (1.0 + static_cast<double>(i)); };
  const double parallel_sum = deterministic_sum(100000, f);
  {
    const SerialLoops serial;
    std::vector<std::pair<int64_t, int64_t>> calls;
    std::vector<int> threads;
    parallel_for(1000, 10, [&](int64_t b, int64_t e) {
      calls.emplace_back(b, e);
      threads.push_back(omp_get_thread_num());
    });
    ASSERT_EQ(calls.size(), 1u);
    EXPECT_EQ(calls[0], std::make_pair(int64_t{0}, int64_t{1000}));
    EXPECT_EQ(threads[0], 0);
    EXPECT_EQ(deterministic_sum(100000, f), parallel_sum);
  }
  omp_set_num_threads(before);
  EXPECT_GT(chunks_of(1000, 10, 2).size(), 1u);
}

}  // namespace
}  // namespace sl::test
