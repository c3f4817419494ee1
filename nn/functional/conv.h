// 2-D and 3-D convolution (cross-correlation, PyTorch's conv2d / conv3d semantics).
//
// Contract:
//   conv2d(x [N, C, H, W], w [O, C, kh, kw], bias [O] or undefined) -> [N, O, Ho, Wo]
//   conv3d(x [N, C, D, H, W], w [O, C, kd, kh, kw], bias) -> [N, O, Do, Ho, Wo]
//   with Ho = (H + 2·pad - dilation·(k - 1) - 1) / stride + 1 per spatial axis.
// - Requires: same floating dtype (F32 or F64) on x, w and bias; stride and dilation >= 1,
//   padding >= 0; every output extent >= 1. Inputs may have any strides. No groups.
// - Guarantees: one tape node with the gradients of x, w and bias. Results are bitwise
//   identical for any OMP_NUM_THREADS: work is split in chunks fixed by the shapes, and the
//   weight gradient is summed over fixed groups of (batch item, spatial tile) in a fixed order.
// - Throws sl::Error naming the op and the shapes on any mismatch.
// Speed (float, AVX-512): stride-1 convolutions run as an implicit GEMM on a zero-padded copy of
// the input (nn/functional/conv_implicit_gemm.h), strided ones as im2col panels into the same register-blocked
// micro-kernel (nn/functional/conv_microkernel.h); the input gradient of a stride-1 convolution is the forward
// convolution of dy with the flipped, transposed kernel. Layers with few positions per image
// (under 96) fold the batch into 48-column panels that span items, on the same micro-kernel for
// the forward pass and the stride-1 input gradient; their weight gradient and strided input
// gradient fold the batch into one im2col GEMM on autodiff's Eigen GEMM, which is also the
// float64 path.
#pragma once
#include <array>
#include <cstdint>

#include "autodiff/tensor.h"

namespace sl::nn {

Tensor conv2d(const Tensor& x, const Tensor& w, const Tensor& bias, std::array<int64_t, 2> stride = {1, 1},
              std::array<int64_t, 2> padding = {0, 0}, std::array<int64_t, 2> dilation = {1, 1});

Tensor conv3d(const Tensor& x, const Tensor& w, const Tensor& bias, std::array<int64_t, 3> stride = {1, 1, 1},
              std::array<int64_t, 3> padding = {0, 0, 0}, std::array<int64_t, 3> dilation = {1, 1, 1});

}  // namespace sl::nn
