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

// Process CPU time in ms (all threads): with OMP_NUM_THREADS=1, a figure that other processes'
// load on a shared machine distorts far less than wall time.
inline double cpu_now_ms() {
  timespec ts{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) * 1e3 + static_cast<double>(ts.tv_nsec) * 1e-6;
}

// best_ms on process CPU time.
template <class F>
double best_cpu_ms(F&& f, int runs = 5, int warmup = 1) {
  for (int i = 0; i < warmup; ++i) f();
  double best = std::numeric_limits<double>::infinity();
  for (int i = 0; i < runs; ++i) {
    const double t0 = cpu_now_ms();
    f();
    best = std::min(best, cpu_now_ms() - t0);
  }
  return best;
}

}  // namespace sl::bench
