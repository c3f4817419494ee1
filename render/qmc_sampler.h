// Owen-scrambled Sobol sample pairs for the path tracer (Burley 2020, "Practical Hash-based
// Owen Scrambling", JCGT 9(4)).
//
// Contract:
// - sobol_pair(index) is the index-th point of the 2D Sobol (0, 2)-sequence: the van der Corput
//   radical inverse in base 2 and Sobol's second dimension. Its first 2^m points put exactly
//   one point in every elementary interval of area 2^-m (stratified in x, y and every
//   2^a × 2^b grid with a + b = m).
// - owen_pair(seed, stream, sample, pair) is sample `sample` of 2D pattern `pair` of one pixel
//   (`stream`): the sample index is shuffled by a nested uniform scramble and the two
//   coordinates are Owen-scrambled, each with its own hash of (seed, stream, pair). So every
//   pair of one pixel, and every pixel, is an independent randomisation of the same net: the
//   first 2^m samples of a pair keep the stratification above, the pairs are decorrelated
//   from each other, and the estimator stays unbiased (each point is uniform on [0, 1)²).
// - Pure functions of their arguments (docs/DESIGN.md, "Randomness"); outputs lie in [0, 1).
#pragma once
#include <cstdint>

#include <glm/glm.hpp>

#include "util/random.h"

namespace sl::render::qmc {

inline uint32_t reverse_bits(uint32_t x) {
  x = ((x >> 1) & 0x55555555u) | ((x & 0x55555555u) << 1);
  x = ((x >> 2) & 0x33333333u) | ((x & 0x33333333u) << 2);
  x = ((x >> 4) & 0x0f0f0f0fu) | ((x & 0x0f0f0f0fu) << 4);
  x = ((x >> 8) & 0x00ff00ffu) | ((x & 0x00ff00ffu) << 8);
  return (x >> 16) | (x << 16);
}

// Sobol's second dimension: generator matrix with columns v_k = Pascal's triangle mod 2,
// built by v ← v ^ (v >> 1) from the top bit.
inline uint32_t sobol_second(uint32_t index) {
  uint32_t r = 0;
  for (uint32_t v = 1u << 31; index != 0; index >>= 1, v ^= v >> 1)
    if (index & 1u) r ^= v;
  return r;
}

// A hash that only lets each bit depend on the bits BELOW it (Laine-Karras style, with
// Burley's constants): on bit-reversed values this is a nested uniform (Owen) scramble.
inline uint32_t laine_karras_permutation(uint32_t x, uint32_t seed) {
  x += seed;
  x ^= x * 0x6c50b47cu;
  x ^= x * 0xb82f1e52u;
  x ^= x * 0xc7afe638u;
  x ^= x * 0x8d22f6e6u;
  return x;
}

inline uint32_t nested_uniform_scramble(uint32_t x, uint32_t seed) {
  return reverse_bits(laine_karras_permutation(reverse_bits(x), seed));
}

struct Pair32 {
  uint32_t x, y;
};
inline Pair32 sobol_pair(uint32_t index) { return {reverse_bits(index), sobol_second(index)}; }

// 32-bit fixed point to [0, 1) as float, never rounding up to 1.
inline float to_unit(uint32_t bits) { return static_cast<float>(bits >> 8) * 0x1.0p-24f; }

inline glm::vec2 owen_pair(uint64_t seed, uint64_t stream, uint64_t sample, uint32_t pair) {
  const uint64_t h = hash_counter(seed ^ 0x5eed50b01ULL, stream, pair);
  const uint32_t shuffle_seed = static_cast<uint32_t>(h), x_seed = static_cast<uint32_t>(h >> 32);
  const uint32_t y_seed = static_cast<uint32_t>(mix64(h));
  const Pair32 p = sobol_pair(nested_uniform_scramble(static_cast<uint32_t>(sample), shuffle_seed));
  return {to_unit(nested_uniform_scramble(p.x, x_seed)), to_unit(nested_uniform_scramble(p.y, y_seed))};
}

}  // namespace sl::render::qmc
