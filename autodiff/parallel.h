// Deterministic parallel loops over OpenMP.
//
// Contract: work is split into chunks whose boundaries depend only on the problem size and a
// fixed grain, never on the thread count. Each index is processed by exactly one call of the
// body, so any body whose result for an index depends only on that index gives bitwise
// identical results for OMP_NUM_THREADS=1 and 2. Reductions use fixed blocks combined in order.
#pragma once
#include <omp.h>

#include <algorithm>
#include <cstdint>
#include <vector>

namespace sl {

// Calls body(begin, end) over [0, n) in chunks of `grain` (the last may be shorter).
template <class Body>
void parallel_for(int64_t n, int64_t grain, Body&& body) {
  if (n <= 0) return;
  grain = std::max<int64_t>(grain, 1);
  const int64_t chunks = (n + grain - 1) / grain;
  if (chunks == 1 || omp_in_parallel()) {
    body(int64_t{0}, n);
    return;
  }
#pragma omp parallel for schedule(static)
  for (int64_t c = 0; c < chunks; ++c) body(c * grain, std::min(n, (c + 1) * grain));
}

// Number of elements summed sequentially into one partial before partials are combined.
constexpr int64_t kReduceBlock = 4096;

// Sum of f(i) for i in [0, n) in double, in a fixed order: blocks of kReduceBlock summed
// sequentially, then the block partials summed in block order.
template <class F>
double deterministic_sum(int64_t n, F&& f) {
  if (n <= 0) return 0.0;
  const int64_t blocks = (n + kReduceBlock - 1) / kReduceBlock;
  std::vector<double> partial(static_cast<size_t>(blocks), 0.0);
  parallel_for(blocks, 1, [&](int64_t b0, int64_t b1) {
    for (int64_t b = b0; b < b1; ++b) {
      double acc = 0.0;
      const int64_t end = std::min(n, (b + 1) * kReduceBlock);
      for (int64_t i = b * kReduceBlock; i < end; ++i) acc += static_cast<double>(f(i));
      partial[static_cast<size_t>(b)] = acc;
    }
  });
  double total = 0.0;
  for (double p : partial) total += p;
  return total;
}

}  // namespace sl
