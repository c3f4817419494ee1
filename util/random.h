// Counter-based random numbers (docs/DESIGN.md, "Randomness").
//
// Contract: every random number is a pure function of (seed, stream, counter) — for example
// (seed, pixel or ray index, sample index). Never of thread or call order, so results are the
// same with any number of threads. The mixer is SplitMix64's finaliser applied in a chain.
#pragma once
#include <cmath>
#include <cstdint>

#include "util/math.h"

namespace sl {

inline uint64_t mix64(uint64_t z) {
  z += 0x9e3779b97f4a7c15ULL;
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
  return z ^ (z >> 31);
}

inline uint64_t hash_counter(uint64_t seed, uint64_t stream, uint64_t counter = 0) {
  return mix64(mix64(mix64(seed) ^ stream) ^ counter);
}

// Uniform in [0, 1), 53 random bits.
inline double uniform01(uint64_t seed, uint64_t stream, uint64_t counter = 0) {
  return static_cast<double>(hash_counter(seed, stream, counter) >> 11) * 0x1.0p-53;
}

// Uniform in [0, 1) as float, never rounding up to 1.
inline float uniform01f(uint64_t seed, uint64_t stream, uint64_t counter = 0) {
  return static_cast<float>(hash_counter(seed, stream, counter) >> 40) * 0x1.0p-24f;
}

// Standard normal by Box-Muller on two counters.
inline double normal01(uint64_t seed, uint64_t stream, uint64_t counter = 0) {
  const double u1 = 1.0 - uniform01(seed, stream, 2 * counter);  // (0, 1]
  const double u2 = uniform01(seed, stream, 2 * counter + 1);
  return std::sqrt(-2.0 * std::log(u1)) * std::cos(kTwoPi * u2);
}

// A small sequential generator for code that draws a few numbers in a fixed order
// (augmentation choices, initialisation). Still counter-based: its state is (seed, stream, n).
class Rng {
 public:
  explicit Rng(uint64_t seed, uint64_t stream = 0) : seed_(seed), stream_(stream) {}
  double uniform() { return uniform01(seed_, stream_, n_++); }
  double uniform(double lo, double hi) { return lo + (hi - lo) * uniform(); }
  double normal() { return normal01(seed_, stream_, n_++); }
  uint64_t next_u64() { return hash_counter(seed_, stream_, n_++); }
  int64_t randint(int64_t n) { return static_cast<int64_t>(next_u64() % static_cast<uint64_t>(n)); }

 private:
  uint64_t seed_, stream_, n_ = 0;
};

}  // namespace sl
