// Shape ops: reshape, permute, slice, concat, stack, pad, expand — with their backward.
//
// Contract: reshape (one dim may be -1) is a view when the input is contiguous and a copy
// otherwise; permute, transpose, slice, expand, squeeze and unsqueeze are always views;
// concat, stack and pad copy. Negative dims count from the end. slice clamps start/end like
// Python and needs step >= 1. Errors name the op, the dims and the shapes.
#pragma once
#include <utility>

#include "autodiff/tensor.h"
#include "autodiff/tape.h"

namespace sl {

Tensor reshape(const Tensor& x, Shape shape);
Tensor flatten(const Tensor& x, int64_t start_dim = 0, int64_t end_dim = -1);
Tensor permute(const Tensor& x, const std::vector<int64_t>& dims);
Tensor transpose(const Tensor& x, int64_t dim0, int64_t dim1);
Tensor slice(const Tensor& x, int64_t dim, int64_t start, int64_t end, int64_t step = 1);
Tensor select(const Tensor& x, int64_t dim, int64_t index);  // slice + drop the dim
Tensor concat(const TensorList& xs, int64_t dim);
Tensor stack(const TensorList& xs, int64_t dim);
// pads[d] = {before, after} for each dim d (a shorter list pads the trailing dims).
Tensor pad(const Tensor& x, const std::vector<std::pair<int64_t, int64_t>>& pads, double value = 0.0);
Tensor expand(const Tensor& x, const Shape& shape);
Tensor squeeze(const Tensor& x, int64_t dim);
Tensor unsqueeze(const Tensor& x, int64_t dim);

int64_t normalize_dim(const char* op, int64_t dim, int64_t ndim);

}  // namespace sl
