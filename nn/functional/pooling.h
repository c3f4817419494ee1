// Max and average pooling over 2-D and 3-D windows, and global average pooling.
//
// Contract:
//   max_pool2d / avg_pool2d (x [N, C, H, W], kernel, stride, padding) -> [N, C, Ho, Wo]
//   max_pool3d / avg_pool3d (x [N, C, D, H, W], ...)                  -> [N, C, Do, Ho, Wo]
//   with Ho = (H + 2·pad - kernel) / stride + 1 (floor mode, as PyTorch's default).
//   global_avg_pool(x [N, C, ...]) -> [N, C], the mean over every spatial position.
// - max pooling treats padding as -inf (never selected); the gradient goes to the first
//   maximal element of each window in scan order, as PyTorch.
// - avg pooling counts padded positions in the divisor (count_include_pad = true, PyTorch's
//   default), so every window divides by the full kernel volume.
// - Requires: F32 or F64, kernel >= 1, stride >= 1, 0 <= padding <= kernel / 2 (as PyTorch),
//   every output extent >= 1. Throws sl::Error naming the op and the shapes otherwise.
// - Guarantees: one tape node; deterministic for any thread count (work split per (n, c) plane).
#pragma once
#include <array>
#include <cstdint>

#include "autodiff/tensor.h"

namespace sl::nn {

Tensor max_pool2d(const Tensor& x, std::array<int64_t, 2> kernel, std::array<int64_t, 2> stride,
                  std::array<int64_t, 2> padding = {0, 0});
Tensor avg_pool2d(const Tensor& x, std::array<int64_t, 2> kernel, std::array<int64_t, 2> stride,
                  std::array<int64_t, 2> padding = {0, 0});
Tensor max_pool3d(const Tensor& x, std::array<int64_t, 3> kernel, std::array<int64_t, 3> stride,
                  std::array<int64_t, 3> padding = {0, 0, 0});
Tensor avg_pool3d(const Tensor& x, std::array<int64_t, 3> kernel, std::array<int64_t, 3> stride,
                  std::array<int64_t, 3> padding = {0, 0, 0});
Tensor global_avg_pool(const Tensor& x);

}  // namespace sl::nn
