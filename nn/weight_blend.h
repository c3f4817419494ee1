// Weight-space interpolation of two trained models (Wortsman et al., "Robust fine-tuning of
// zero-shot models", CVPR 2022, "WiSE-FT"): θ(t) = (1 − t)·θa + t·θb, tensor by tensor. Between two
// fine-tunings of one parent the straight line often keeps most of what each learned; between
// unrelated runs it does not, so the caller measures the blend (docs/RESULTS.md, 2026-11-27).
//
// Contract:
// - `a` and `b` hold the same names, shapes and dtypes (nn::compare_state); otherwise throws ONE
//   sl::Error listing what differs. t is finite and in [0, 1], else throws naming it.
// - Float tensors (F32, F64) are blended in double and rounded once to their dtype; t = 0 returns
//   a's values and t = 1 b's, bit for bit. Integer tensors (counters such as BatchNorm's
//   num_batches_tracked) are blended the same way and rounded to the nearest integer.
//   Non-contiguous views are read in logical order.
// - Every output tensor is new storage; neither input is modified.
#pragma once
#include "nn/module.h"

namespace sl::nn {

StateDict blend_states(const StateDict& a, const StateDict& b, double t);

}  // namespace sl::nn
