// Folding an eval-mode batch norm into the convolution before it, for inference (issue 52).
//
// Contract:
// - fold_batch_norm(conv, bn): `conv` whose output feeds `bn` (bn.features == conv's out
//   channels; bn with running statistics) becomes conv' with, per output channel o,
//     w'[o] = w[o]·s[o],  b'[o] = (b[o] − μ[o])·s[o] + β[o],  s = γ / √(σ² + ε)
//   (b = 0 when conv had no bias; γ = 1, β = 0 without affine), computed in float64 and rounded
//   once to the conv's dtype; bn becomes the identity (an activation fused into it is still
//   applied). bn(conv(x)) and conv'(x) are the same function; they differ by rounding only:
//   the folded product w·s is rounded once per weight instead of once per output, and the sum is
//   the same length, so each output differs by at most about (K + 2)·u·s·Σ|w||x| (K the taps
//   times input channels, u the dtype's unit roundoff). tests/nn/batch_norm_folding_test.cpp
//   measures it through a whole ResNet.
// - Irreversible and for inference only: a folded bn throws sl::Error in training mode, conv
//   gains a `bias` parameter when it had none, and the state dict no longer matches a checkpoint
//   (load first, fold after).
// - Throws sl::Error for a channel mismatch, a bn without running statistics, or a bn already
//   folded.
#pragma once
#include "nn/modules/batch_norm.h"
#include "nn/modules/conv.h"

namespace sl::nn {

void fold_batch_norm(ConvNd& conv, BatchNormNd& bn);

}  // namespace sl::nn
