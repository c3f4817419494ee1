// Reductions over axes, logsumexp and L2 normalisation.
//
// Contract: axes may be negative; an empty axis list reduces over all axes. keepdim keeps
// reduced axes as size 1. Sums accumulate in double in a fixed block order (parallel.h), so
// results are bitwise identical for any thread count. Reducing a size-0 axis gives 0 for sum,
// NaN-free 0 for mean (0/0 is reported as an error instead), and throws for max/min.
// max/min split the gradient evenly between tied maxima (as torch.amax).
// logsumexp is computed as m + log Σ exp(x - m) with m the (finite) max; all -inf gives -inf.
// normalize(x, axis, eps) = x / max(‖x‖, eps) as torch.nn.functional.normalize: a zero vector
// maps to 0 with gradient g / eps.
#pragma once
#include "autodiff/tensor.h"

namespace sl {

Tensor sum(const Tensor& x, std::vector<int64_t> axes = {}, bool keepdim = false);
Tensor mean(const Tensor& x, std::vector<int64_t> axes = {}, bool keepdim = false);
Tensor max(const Tensor& x, std::vector<int64_t> axes = {}, bool keepdim = false);
Tensor min(const Tensor& x, std::vector<int64_t> axes = {}, bool keepdim = false);
Tensor logsumexp(const Tensor& x, int64_t axis, bool keepdim = false);
Tensor normalize(const Tensor& x, int64_t axis, double eps = 1e-12);

// Sums a broadcast gradient back to `shape` (the inverse of broadcasting).
Tensor sum_to(const Tensor& x, const Shape& shape);

}  // namespace sl
