// Inverted dropout with a counter-based mask (docs/DESIGN.md, "Randomness").
//
// Contract: dropout(x, p, training, seed, step) returns x unchanged (the same tensor) when
// training is false or p == 0; otherwise y = x · mask / (1 - p) where element i is kept iff
// uniform01(seed, step, i) >= p — a pure function of (seed, step, logical element index), so
// the mask is the same for any thread count and is replayed exactly by backward.
// Requires 0 <= p < 1 and a floating x (any strides). One tape node.
#pragma once
#include <cstdint>

#include "autodiff/tensor.h"

namespace sl::nn {

Tensor dropout(const Tensor& x, double p, bool training, uint64_t seed, uint64_t step);

}  // namespace sl::nn
