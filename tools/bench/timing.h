// Timing helpers for benchmarks: warm-up, then the best of several runs.
#pragma once
#include <algorithm>
#include <chrono>
#include <limits>

#include <time.h>

namespace sl::bench {

inline double now_ms() {
  using clock = std::chrono::steady_clock;
  return std::chrono::duration<double, std::milli>(clock::now().time_since_epoch()).count();
}

// Process CPU time in ms (all threads): with OMP_NUM_THREADS=1, a figure that other processes'
// load on a shared machine distorts far less than wall time.
inline double cpu_now_ms() {
  timespec ts{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) * 1e3 + static_cast<double>(ts.tv_nsec) * 1e-6;
}

// The least time in ms, on `clock` (now_ms or cpu_now_ms), of `runs` calls of f after `warmup`
// untimed calls.
template <class Clock, class F>
double best_time_ms(Clock&& clock, F&& f, int runs, int warmup) {
  for (int i = 0; i < warmup; ++i) f();
  double best = std::numeric_limits<double>::infinity();
  for (int i = 0; i < runs; ++i) {
    const double t0 = clock();
    f();
    best = std::min(best, clock() - t0);
  }
  return best;
}

// Best wall time in ms of `runs` calls of f after `warmup` untimed calls.
template <class F>
double best_ms(F&& f, int runs = 5, int warmup = 1) {
  return best_time_ms(now_ms, f, runs, warmup);
}

// best_ms on process CPU time.
template <class F>
double best_cpu_ms(F&& f, int runs = 5, int warmup = 1) {
  return best_time_ms(cpu_now_ms, f, runs, warmup);
}

}  // namespace sl::bench
