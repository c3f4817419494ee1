#include "autodiff/reduce.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <type_traits>
#include <vector>

#include "autodiff/elementwise.h"
#include "autodiff/map.h"
#include "autodiff/shape_ops.h"
#include "autodiff/tape.h"
#include "autodiff/unary.h"
#include "autodiff/vector_math.h"

namespace sl {
namespace {

struct ReducePlan {
  std::vector<int64_t> axes;  // sorted, unique, non-negative
  Shape out_shape;            // without keepdim
  Shape keep_shape;           // with reduced axes as 1
  int64_t outer = 1, inner = 1;
};

ReducePlan plan_reduce(const char* op, const Tensor& x, std::vector<int64_t> axes) {
  ReducePlan p;
  const int64_t nd = x.dim();
  if (axes.empty())
    for (int64_t d = 0; d < nd; ++d) axes.push_back(d);
  for (int64_t& a : axes) a = normalize_dim(op, a, nd);
  std::sort(axes.begin(), axes.end());
  SL_CHECK(std::adjacent_find(axes.begin(), axes.end()) == axes.end(), op,
           ": an axis is repeated for shape ", shape_str(x.shape()));
  p.axes = axes;
  for (int64_t d = 0; d < nd; ++d) {
    const bool reduced = std::binary_search(axes.begin(), axes.end(), d);
    p.keep_shape.push_back(reduced ? 1 : x.shape()[d]);
    if (reduced) {
      p.inner *= x.shape()[d];
    } else {
      p.out_shape.push_back(x.shape()[d]);
      p.outer *= x.shape()[d];
    }
  }
  return p;
}

// x rearranged as a contiguous [outer, inner] block with the reduced axes last.
Tensor rows_view(const Tensor& x, const ReducePlan& p) {
  std::vector<int64_t> perm;
  for (int64_t d = 0; d < x.dim(); ++d)
    if (!std::binary_search(p.axes.begin(), p.axes.end(), d)) perm.push_back(d);
  for (int64_t a : p.axes) perm.push_back(a);
  NoGradGuard no_grad;
  return permute(x.detach(), perm).contiguous();
}

// One reduction block's sum in double: float32 through vm::sum (32 partial sums, the same bits
// on every SIMD level), float64 through block_sum.
template <class T>
double block_total(const T* p, int64_t b, int64_t e) {
  if constexpr (std::is_same_v<T, float>)
    return vm::sum(p + b, e - b);
  else
    return block_sum(b, e, [p](int64_t i) { return p[i]; });
}

// Row sum in the fixed block order of parallel.h: identical bits whichever thread runs it.
template <class T>
double row_sum(const T* p, int64_t n) {
  double total = 0.0;
  for (int64_t b = 0; b < n; b += kReduceBlock) total += block_total(p, b, std::min(n, b + kReduceBlock));
  return total;
}

// The whole array's sum: blocks of kReduceBlock in parallel, partials summed in block order
// (parallel.h deterministic_sum's order).
template <class T>
double array_sum(const T* p, int64_t n) {
  if (n <= 0) return 0.0;
  const int64_t blocks = (n + kReduceBlock - 1) / kReduceBlock;
  std::vector<double> partial(static_cast<size_t>(blocks), 0.0);
  parallel_for(blocks, 1, [&](int64_t b0, int64_t b1) {
    for (int64_t b = b0; b < b1; ++b)
      partial[static_cast<size_t>(b)] = block_total(p, b * kReduceBlock, std::min(n, (b + 1) * kReduceBlock));
  });
  double total = 0.0;
  for (double v : partial) total += v;
  return total;
}

Tensor sum_kernel(const Tensor& x, const ReducePlan& p) {
  Tensor rows = rows_view(x, p);
  Tensor out = Tensor::empty(p.out_shape, x.dtype());
  SL_DISPATCH_FLOAT(x.dtype(), "sum", [&] {
    using T = scalar_t;
    const T* src = rows.data<T>();
    T* dst = out.data<T>();
    if (p.outer == 1) {
      dst[0] = static_cast<T>(array_sum(src, p.inner));
    } else {
      parallel_for(p.outer, std::max<int64_t>(1, 32768 / std::max<int64_t>(p.inner, 1)),
                   [&](int64_t r0, int64_t r1) {
                     for (int64_t r = r0; r < r1; ++r) dst[r] = static_cast<T>(row_sum(src + r * p.inner, p.inner));
                   });
    }
  });
  return out;
}

template <bool IsMax>
Tensor extreme(const char* op, const Tensor& x, std::vector<int64_t> axes, bool keepdim) {
  const ReducePlan p = plan_reduce(op, x, std::move(axes));
  SL_CHECK(p.inner > 0 || p.outer == 0, op, ": cannot reduce over an empty axis of shape ", shape_str(x.shape()));
  Tensor rows = rows_view(x, p);
  Tensor out = Tensor::empty(p.out_shape, x.dtype());
  SL_DISPATCH_FLOAT(x.dtype(), op, [&] {
    using T = scalar_t;
    const T* src = rows.data<T>();
    T* dst = out.data<T>();
    parallel_for(p.outer, std::max<int64_t>(1, 32768 / std::max<int64_t>(p.inner, 1)), [&](int64_t r0, int64_t r1) {
      for (int64_t r = r0; r < r1; ++r) {
        const T* row = src + r * p.inner;
        T m = row[0];
        for (int64_t i = 1; i < p.inner; ++i) {
          const T v = row[i];
          if (std::isnan(v) || (IsMax ? v > m : v < m)) m = v;
          if (std::isnan(m)) break;
        }
        dst[r] = m;
      }
    });
  });
  const Shape keep = p.keep_shape;
  Tensor y = keepdim ? Tensor::make_view(out, keep, contiguous_strides(keep), 0) : out;
  if (needs_grad({x})) {
    const Tensor xd = x.detach(), yk = Tensor::make_view(out, keep, contiguous_strides(keep), 0);
    const std::vector<int64_t> ax = p.axes;
    record(op, {x}, {y}, [=](const TensorList& g) {
      Tensor mask = eq(xd, yk);
      Tensor count = sum(mask, ax, true);
      return TensorList{div(mul(mask, reshape(g[0], keep)), count)};
    });
  }
  return y;
}

}  // namespace

Tensor sum(const Tensor& x, std::vector<int64_t> axes, bool keepdim) {
  const ReducePlan p = plan_reduce("sum", x, std::move(axes));
  Tensor out = sum_kernel(x, p);
  if (keepdim) out = Tensor::make_view(out, p.keep_shape, contiguous_strides(p.keep_shape), 0);
  if (needs_grad({x})) {
    const Shape in_shape = x.shape(), keep = p.keep_shape;
    record("sum", {x}, {out}, [=](const TensorList& g) {
      return TensorList{expand(reshape(g[0], keep), in_shape)};
    });
  }
  return out;
}

Tensor mean(const Tensor& x, std::vector<int64_t> axes, bool keepdim) {
  const ReducePlan p = plan_reduce("mean", x, axes);
  SL_CHECK(p.inner > 0, "mean: cannot average over an empty axis of shape ", shape_str(x.shape()));
  return mul_scalar(sum(x, std::move(axes), keepdim), 1.0 / static_cast<double>(p.inner));
}

Tensor max(const Tensor& x, std::vector<int64_t> axes, bool keepdim) {
  return extreme<true>("max", x, std::move(axes), keepdim);
}

Tensor min(const Tensor& x, std::vector<int64_t> axes, bool keepdim) {
  return extreme<false>("min", x, std::move(axes), keepdim);
}

Tensor logsumexp(const Tensor& x, int64_t axis, bool keepdim) {
  Tensor y_keep;
  {
    NoGradGuard no_grad;
    const Tensor xd = x.detach();
    Tensor m = max(xd, {axis}, true);
    // An all -inf (or +inf) row would give inf - inf: shift by 0 there instead.
    m = detail::map_n("logsumexp", [](auto v) { return std::isfinite(v) ? v : decltype(v)(0); }, m);
    y_keep = add(m, log(sum(exp(sub(xd, m)), {axis}, true)));
  }
  const int64_t ax = normalize_dim("logsumexp", axis, x.dim());
  Tensor y = keepdim ? y_keep : squeeze(y_keep, ax);
  y = Tensor::make_view(y, y.shape(), y.strides(), y.offset());  // fresh handle for the tape
  if (needs_grad({x})) {
    const Tensor xd = x.detach(), yk = y_keep.detach();
    const Shape keep = y_keep.shape();
    record("logsumexp", {x}, {y}, [=](const TensorList& g) {
      // d/dx logsumexp = softmax(x); exp(x - y) is 0 (not NaN) where x = -inf.
      Tensor soft = detail::map_n("logsumexp", [](auto v, auto l) {
        return std::isinf(l) ? decltype(v)(0) : std::exp(v - l); }, xd, yk);
      return TensorList{mul(soft, reshape(g[0], keep))};
    });
  }
  return y;
}

Tensor normalize(const Tensor& x, int64_t axis, double eps) {
  Tensor norm, y;
  {
    NoGradGuard no_grad;
    norm = sqrt(sum(square(x.detach()), {axis}, true));
    y = div(x.detach(), clamp(norm, eps, std::numeric_limits<double>::infinity()));
  }
  if (needs_grad({x})) {
    const Tensor yd = y.detach(), nd = norm;
    const int64_t ax = axis;
    record("normalize", {x}, {y}, [=](const TensorList& g) {
      const Tensor denom = clamp(nd, eps, std::numeric_limits<double>::infinity());
      const Tensor dot = sum(mul(g[0], yd), {ax}, true);
      const Tensor above = gt(nd, Tensor::scalar(eps, nd.dtype()));
      return TensorList{div(sub(g[0], mul(mul(yd, dot), above)), denom)};
    });
  }
  return y;
}

Tensor sum_to(const Tensor& x, const Shape& shape) {
  if (x.shape() == shape) return x;
  const int64_t lead = x.dim() - static_cast<int64_t>(shape.size());
  SL_CHECK(lead >= 0, "sum_to: cannot reduce ", x.describe(), " to ", shape_str(shape));
  std::vector<int64_t> axes;
  for (int64_t d = 0; d < x.dim(); ++d) {
    if (d < lead) {
      axes.push_back(d);
      continue;
    }
    const int64_t target = shape[static_cast<size_t>(d - lead)];
    if (target == 1 && x.shape()[d] != 1) axes.push_back(d);
    else SL_CHECK(target == x.shape()[d], "sum_to: cannot reduce ", x.describe(), " to ", shape_str(shape));
  }
  if (axes.empty()) return reshape(x, shape);
  return reshape(sum(x, axes, true), shape);
}

}  // namespace sl
