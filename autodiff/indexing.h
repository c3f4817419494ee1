// Index ops: index_select, gather, scatter_add (PyTorch semantics), with their backward.
//
// Contract: indices are I64 tensors; every index is bounds-checked and an out-of-range index
// throws naming the op, the index and the dim size. Gradients flow to the floating operands.
//   index_select(x, dim, idx[n])      -> x with dim resized to n
//   gather(x, dim, idx)               -> out[..i..] = x[.. idx[..i..] ..]  (idx has x's rank)
//   scatter_add(x, dim, idx, src)     -> x + src added at idx along dim
// scatter_add is deterministic: each output row is accumulated in index order.
#pragma once
#include "autodiff/tensor.h"

namespace sl {

Tensor index_select(const Tensor& x, int64_t dim, const Tensor& index);
Tensor gather(const Tensor& x, int64_t dim, const Tensor& index);
Tensor scatter_add(const Tensor& x, int64_t dim, const Tensor& index, const Tensor& src);

}  // namespace sl
