// Upsampling by integer factors (PyTorch's F.interpolate semantics).
//
// Contract:
//   upsample_nearest2d(x [N, C, H, W], s)       -> [N, C, s·H, s·W]; out[i] = x[floor(i / s)].
//   upsample_bilinear2d(x [N, C, H, W], s, ac)  -> [N, C, s·H, s·W]
//   upsample_nearest3d(x [N, C, D, H, W], s)    -> [N, C, s·D, s·H, s·W]
//   upsample_trilinear3d(x [N, C, D, H, W], s, ac) -> [N, C, s·D, s·H, s·W]
//   Linear modes follow PyTorch with scale_factor = s: align_corners = false samples source
//   coordinate (i + 1/2)/s - 1/2 clamped at 0; align_corners = true maps the corners onto each
//   other, src = i·(in - 1)/(out - 1).
// - Requires: F32 or F64, any strides, scale >= 1. Throws sl::Error naming the op otherwise.
// - Guarantees: one tape node. Linear modes are computed one axis at a time (the weights are
//   separable); the backward runs the passes' adjoints, each accumulating one slice per task in
//   a fixed order, so gradients are bitwise identical for any thread count.
//
// Why UNets here use Upsample + conv instead of a transposed convolution: a strided
// transposed convolution overlaps its kernel unevenly, which prints checkerboard artifacts into
// decoded volumes (Odena et al., "Deconvolution and Checkerboard Artifacts", 2016); resizing
// first and then convolving has no uneven overlap, and it reuses the fast stride-1 conv path.
#pragma once
#include <cstdint>

#include "autodiff/tensor.h"

namespace sl::nn {

Tensor upsample_nearest2d(const Tensor& x, int64_t scale);
Tensor upsample_bilinear2d(const Tensor& x, int64_t scale, bool align_corners = false);
Tensor upsample_nearest3d(const Tensor& x, int64_t scale);
Tensor upsample_trilinear3d(const Tensor& x, int64_t scale, bool align_corners = false);

}  // namespace sl::nn
