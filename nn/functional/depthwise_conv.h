// Depthwise 2-D convolution: PyTorch's conv2d with groups = C and one filter per channel, the
// spatial half of a MobileNetV2 inverted residual block.
//
// Contract:
//   depthwise_conv2d(x [N, C, H, W], w [C, 1, kh, kw], bias [C] or undefined) -> [N, C, Ho, Wo],
//   y[n, c, i, j] = bias[c] + Σ_{u,v} w[c, 0, u, v] · x[n, c, i·sh − ph + u, j·sw − pw + v]
//   with zero padding and Ho = (H + 2·ph − kh) / sh + 1 (likewise Wo).
// - Requires: the same floating dtype (F32 or F64) on x, w and bias; stride >= 1, padding >= 0;
//   every output extent >= 1. Inputs may have any strides (they are made contiguous).
// - Guarantees: one tape node with the gradients of x, w and bias. Results are bitwise identical
//   for any OMP_NUM_THREADS: work is split by (n, c) planes, each computed by one call in a fixed
//   order, and the weight and bias gradients are summed per plane and then over the batch in
//   item order, per channel, in double. Padding is a zero-filled copy of the plane; nothing is
//   read out of bounds.
// - Throws sl::Error naming the op and the shapes on any mismatch.
// Speed: each plane is copied once into a zero-padded buffer whose rows are split into their
// `sw` column phases, so every tap of every stride reads a contiguous run; 3×3 kernels keep the
// nine taps of 16 output columns in registers. The input gradient of a stride-1 convolution
// (padding < kernel) is the forward kernel on the padded dy with the flipped filter; otherwise it
// is scattered into a padded plane.
#pragma once
#include <array>
#include <cstdint>

#include "autodiff/tensor.h"

namespace sl::nn {

Tensor depthwise_conv2d(const Tensor& x, const Tensor& w, const Tensor& bias, std::array<int64_t, 2> stride = {1, 1},
                        std::array<int64_t, 2> padding = {0, 0});

}  // namespace sl::nn
