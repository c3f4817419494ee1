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
#include <utility>
#include <vector>

namespace sl {

namespace detail {
inline int& serial_loops_depth() {
  thread_local int depth = 0;
  return depth;
}
}  // namespace detail

// While a SerialLoops lives on a thread, the loops below called on that thread run on it alone,
// as inside a parallel region: one call of the body for the whole range, which by the contract
// above gives the same results. For code that schedules its
// own parallelism or must not wait on other threads: lighting inference (train/inference.cpp)
// runs its independent parts as tasks of one team and everything else on one thread, since on a
// loaded machine every parallel loop can wait a scheduler tick for a descheduled thread.
class SerialLoops {
 public:
  SerialLoops() { ++detail::serial_loops_depth(); }
  ~SerialLoops() { --detail::serial_loops_depth(); }
  SerialLoops(const SerialLoops&) = delete;
  SerialLoops& operator=(const SerialLoops&) = delete;
};

namespace detail {
// The chunk length for n items at `grain`: `grain`, except that a loop of 2 to kBalancedChunks
// chunks has its count rounded up to a multiple of 4 (shorter chunks; else to an even count), so
// that 2 or 4 threads get near-equal shares under static scheduling. 3 chunks on 2 threads left
// one idle for a third of the loop (the Winograd weight transform of ResNet-18's 128-channel
// layers). A function of (n, grain) only, never of the thread count.
inline constexpr int64_t kBalancedChunks = 32;
inline int64_t balanced_grain(int64_t n, int64_t grain) {
  grain = std::max<int64_t>(grain, 1);
  const int64_t chunks = (n + grain - 1) / grain;
  if (chunks < 2 || chunks > kBalancedChunks || chunks % 4 == 0) return grain;
  const int64_t rounded = (chunks + 3) / 4 * 4;
  // The chunks of ceil(n / rounded) items may still be odd in number (6 items in 4 chunks are
  // 3 chunks of 2): shorten them a little more until the count is even, or keep the grain.
  for (int64_t g = (n + rounded - 1) / rounded, tries = 0; g >= 1 && tries < 8; --g, ++tries)
    if (((n + g - 1) / g) % 2 == 0) return g;
  return grain;
}

// body(begin, end) over [0, n) in chunks of balanced_grain(n, grain), scheduled statically or
// dynamically.
template <bool kDynamic, class Body>
void for_chunks(int64_t n, int64_t grain, Body&& body) {
  if (n <= 0) return;
  grain = balanced_grain(n, grain);
  const int64_t chunks = (n + grain - 1) / grain;
  if (chunks == 1 || omp_in_parallel() || serial_loops_depth() > 0) {
    body(int64_t{0}, n);
    return;
  }
  if constexpr (kDynamic) {
#pragma omp parallel for schedule(dynamic, 1)
    for (int64_t c = 0; c < chunks; ++c) body(c * grain, std::min(n, (c + 1) * grain));
  } else {
#pragma omp parallel for schedule(static)
    for (int64_t c = 0; c < chunks; ++c) body(c * grain, std::min(n, (c + 1) * grain));
  }
}
}  // namespace detail

// Calls body(begin, end) over [0, n) in chunks of about `grain` (detail::balanced_grain; the
// last may be shorter).
template <class Body>
void parallel_for(int64_t n, int64_t grain, Body&& body) {
  detail::for_chunks<false>(n, grain, std::forward<Body>(body));
}

// The same with chunks handed out dynamically, for bodies whose cost varies widely by index
// (adaptive sample counts). Which thread runs a chunk varies; what each index computes does not.
template <class Body>
void parallel_for_dynamic(int64_t n, int64_t grain, Body&& body) {
  detail::for_chunks<true>(n, grain, std::forward<Body>(body));
}

// Number of elements summed sequentially into one partial before partials are combined.
constexpr int64_t kReduceBlock = 4096;

// Sum of f(i) for i in [b, e) (at most one block) in double, in a fixed order: eight
// interleaved accumulators (so the adds pipeline), combined pairwise at the end.
template <class F>
double block_sum(int64_t b, int64_t e, F&& f) {
  double acc[8] = {0, 0, 0, 0, 0, 0, 0, 0};
  int64_t i = b;
  for (; i + 8 <= e; i += 8)
    for (int k = 0; k < 8; ++k) acc[k] += static_cast<double>(f(i + k));
  for (int k = 0; i < e; ++i, ++k) acc[k] += static_cast<double>(f(i));
  return ((acc[0] + acc[1]) + (acc[2] + acc[3])) + ((acc[4] + acc[5]) + (acc[6] + acc[7]));
}

// Sum of f(i) for i in [0, n) in double: blocks of kReduceBlock summed by block_sum, then the
// block partials summed in block order. Identical bits for any thread count.
template <class F>
double deterministic_sum(int64_t n, F&& f) {
  if (n <= 0) return 0.0;
  const int64_t blocks = (n + kReduceBlock - 1) / kReduceBlock;
  std::vector<double> partial(static_cast<size_t>(blocks), 0.0);
  parallel_for(blocks, 1, [&](int64_t b0, int64_t b1) {
    for (int64_t b = b0; b < b1; ++b)
      partial[static_cast<size_t>(b)] = block_sum(b * kReduceBlock, std::min(n, (b + 1) * kReduceBlock), f);
  });
  double total = 0.0;
  for (double p : partial) total += p;
  return total;
}

}  // namespace sl
