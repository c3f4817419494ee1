// Fully connected layer: y = x · wᵀ + bias (PyTorch's F.linear).
//
// Contract: x [..., in], w [out, in], bias [out] or undefined -> [..., out]. Same floating dtype
// everywhere; any strides. One tape node; runs on autodiff's panel-split GEMM, so results are
// bitwise identical for any thread count. Throws sl::Error naming the shapes on a mismatch.
#pragma once
#include "autodiff/tensor.h"

namespace sl::nn {

Tensor linear(const Tensor& x, const Tensor& w, const Tensor& bias);

}  // namespace sl::nn
