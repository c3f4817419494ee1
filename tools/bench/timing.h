// Timing helpers for benchmarks: warm-up, then the best of several runs.
#pragma once
#include <algorithm>
#include <chrono>
#include <limits>

namespace sl::bench {

inline double now_ms() {
  using clock = std::chrono::steady_clock;
  return std::chrono::duration<double, std::milli>(clock::now().time_since_epoch()).count();
}

// Best wall time in ms of `runs` calls of f after `warmup` untimed calls.
template <class F>
double best_ms(F&& f, int runs = 5, int warmup = 1) {
  for (int i = 0; i < warmup; ++i) f();
  double best = std::numeric_limits<double>::infinity();
  for (int i = 0; i < runs; ++i) {
    const double t0 = now_ms();
    f();
    best = std::min(best, now_ms() - t0);
  }
  return best;
}

}  // namespace sl::bench
