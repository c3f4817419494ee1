#include "autodiff/shape_ops.h"

#include <algorithm>

#include "autodiff/reduce.h"

namespace sl {

int64_t normalize_dim(const char* op, int64_t dim, int64_t ndim) {
  const int64_t d = dim < 0 ? dim + ndim : dim;
  SL_CHECK(d >= 0 && d < ndim, op, ": dim ", dim, " is out of range for a ", ndim, "-d tensor");
  return d;
}

Tensor reshape(const Tensor& x, Shape shape) {
  int64_t known = 1, infer = -1;
  for (size_t i = 0; i < shape.size(); ++i) {
    if (shape[i] == -1) {
      SL_CHECK(infer < 0, "reshape: more than one -1 in ", shape_str(shape));
      infer = static_cast<int64_t>(i);
    } else {
      SL_CHECK(shape[i] >= 0, "reshape: negative size in ", shape_str(shape));
      known *= shape[i];
    }
  }
  if (infer >= 0) {
    SL_CHECK(known > 0 && x.numel() % known == 0, "reshape: cannot reshape ", x.describe(), " to ", shape_str(shape));
    shape[static_cast<size_t>(infer)] = x.numel() / known;
  }
  SL_CHECK(shape_numel(shape) == x.numel(), "reshape: cannot reshape ", x.describe(), " to ", shape_str(shape));
  const Tensor src = x.contiguous();
  Tensor y = Tensor::make_view(src, shape, contiguous_strides(shape), src.offset());
  if (needs_grad({src})) {
    const Shape in_shape = src.shape();
    record("reshape", {src}, {y}, [in_shape](const TensorList& g) { return TensorList{reshape(g[0], in_shape)}; });
  }
  return y;
}

Tensor flatten(const Tensor& x, int64_t start_dim, int64_t end_dim) {
  if (x.dim() == 0) return reshape(x, {1});
  const int64_t s = normalize_dim("flatten", start_dim, x.dim());
  const int64_t e = normalize_dim("flatten", end_dim, x.dim());
  Shape shape;
  for (int64_t d = 0; d < s; ++d) shape.push_back(x.shape()[d]);
  int64_t m = 1;
  for (int64_t d = s; d <= e; ++d) m *= x.shape()[d];
  shape.push_back(m);
  for (int64_t d = e + 1; d < x.dim(); ++d) shape.push_back(x.shape()[d]);
  return reshape(x, shape);
}

Tensor permute(const Tensor& x, const std::vector<int64_t>& dims) {
  const int64_t nd = x.dim();
  SL_CHECK(static_cast<int64_t>(dims.size()) == nd, "permute: ", dims.size(), " dims for shape ", shape_str(x.shape()));
  Shape shape(nd), strides(nd);
  std::vector<int64_t> inverse(nd, -1);
  for (int64_t i = 0; i < nd; ++i) {
    const int64_t d = normalize_dim("permute", dims[i], nd);
    SL_CHECK(inverse[d] < 0, "permute: dim ", dims[i], " repeated in ", shape_str(dims));
    inverse[d] = i;
    shape[i] = x.shape()[d];
    strides[i] = x.strides()[d];
  }
  Tensor y = Tensor::make_view(x, shape, strides, x.offset());
  if (needs_grad({x}))
    record("permute", {x}, {y}, [inverse](const TensorList& g) { return TensorList{permute(g[0], inverse)}; });
  return y;
}

Tensor transpose(const Tensor& x, int64_t dim0, int64_t dim1) {
  std::vector<int64_t> dims(x.dim());
  for (int64_t i = 0; i < x.dim(); ++i) dims[i] = i;
  std::swap(dims[normalize_dim("transpose", dim0, x.dim())], dims[normalize_dim("transpose", dim1, x.dim())]);
  return permute(x, dims);
}

Tensor slice(const Tensor& x, int64_t dim, int64_t start, int64_t end, int64_t step) {
  const int64_t d = normalize_dim("slice", dim, x.dim());
  SL_CHECK(step >= 1, "slice: step must be >= 1, got ", step);
  const int64_t n = x.shape()[d];
  auto clampi = [n](int64_t i) { return std::clamp<int64_t>(i < 0 ? i + n : i, 0, n); };
  const int64_t s = clampi(start), e = std::max(clampi(end), clampi(start));
  Shape shape = x.shape(), strides = x.strides();
  shape[d] = (e - s + step - 1) / step;
  strides[d] *= step;
  Tensor y = Tensor::make_view(x, shape, strides, x.offset() + s * x.strides()[d]);
  if (needs_grad({x})) {
    const Shape in_shape = x.shape();
    const DType dt = x.dtype();
    record("slice", {x}, {y}, [=](const TensorList& g) {
      Tensor gx = Tensor::zeros(in_shape, dt);
      slice(gx, d, s, e, step).copy_(g[0]);
      return TensorList{gx};
    });
  }
  return y;
}

Tensor select(const Tensor& x, int64_t dim, int64_t index) {
  const int64_t d = normalize_dim("select", dim, x.dim());
  const int64_t n = x.shape()[d];
  SL_CHECK(index >= -n && index < n, "select: index ", index, " out of range for dim ", dim, " of ", x.describe());
  const int64_t i = index < 0 ? index + n : index;
  return squeeze(slice(x, d, i, i + 1), d);
}

Tensor concat(const TensorList& xs, int64_t dim) {
  SL_CHECK(!xs.empty(), "concat: no tensors");
  const Tensor& first = xs[0];
  const int64_t d = normalize_dim("concat", dim, first.dim());
  Shape shape = first.shape();
  shape[d] = 0;
  for (const Tensor& t : xs) {
    SL_CHECK(t.dim() == first.dim() && t.dtype() == first.dtype(), "concat: ", t.describe(), " does not match ",
             first.describe());
    for (int64_t k = 0; k < t.dim(); ++k)
      SL_CHECK(k == d || t.shape()[k] == first.shape()[k], "concat along dim ", dim, ": shapes ",
               shape_str(first.shape()), " and ", shape_str(t.shape()), " differ in dim ", k);
    shape[d] += t.shape()[d];
  }
  Tensor y = Tensor::empty(shape, first.dtype());
  std::vector<int64_t> starts;
  int64_t at = 0;
  for (const Tensor& t : xs) {
    starts.push_back(at);
    slice(y.detach(), d, at, at + t.shape()[d]).copy_(t);
    at += t.shape()[d];
  }
  if (needs_grad(xs)) {
    std::vector<int64_t> sizes;
    for (const Tensor& t : xs) sizes.push_back(t.shape()[d]);
    record("concat", xs, {y}, [=](const TensorList& g) {
      TensorList r;
      for (size_t i = 0; i < sizes.size(); ++i) r.push_back(slice(g[0], d, starts[i], starts[i] + sizes[i]));
      return r;
    });
  }
  return y;
}

Tensor stack(const TensorList& xs, int64_t dim) {
  SL_CHECK(!xs.empty(), "stack: no tensors");
  const int64_t d = normalize_dim("stack", dim, xs[0].dim() + 1);
  TensorList u;
  for (const Tensor& t : xs) {
    SL_CHECK(t.shape() == xs[0].shape(), "stack: shapes ", shape_str(xs[0].shape()), " and ", shape_str(t.shape()),
             " differ");
    u.push_back(unsqueeze(t, d));
  }
  return concat(u, d);
}

Tensor pad(const Tensor& x, const std::vector<std::pair<int64_t, int64_t>>& pads, double value) {
  SL_CHECK(static_cast<int64_t>(pads.size()) <= x.dim(), "pad: ", pads.size(), " pads for ", x.describe());
  const int64_t lead = x.dim() - static_cast<int64_t>(pads.size());
  Shape shape = x.shape();
  std::vector<int64_t> before(x.dim(), 0);
  for (size_t i = 0; i < pads.size(); ++i) {
    SL_CHECK(pads[i].first >= 0 && pads[i].second >= 0, "pad: negative padding (", pads[i].first, ", ",
             pads[i].second, ")");
    before[lead + i] = pads[i].first;
    shape[lead + i] += pads[i].first + pads[i].second;
  }
  Tensor y = Tensor::full(shape, value, x.dtype());
  auto interior = [before](const Tensor& t, const Shape& inner) {
    Tensor v = t;
    for (size_t dd = 0; dd < inner.size(); ++dd) v = slice(v, dd, before[dd], before[dd] + inner[dd]);
    return v;
  };
  {
    NoGradGuard no_grad;
    interior(y.detach(), x.shape()).copy_(x);
  }
  if (needs_grad({x})) {
    const Shape in_shape = x.shape();
    record("pad", {x}, {y}, [=](const TensorList& g) { return TensorList{interior(g[0], in_shape)}; });
  }
  return y;
}

Tensor expand(const Tensor& x, const Shape& shape) {
  const int64_t lead = static_cast<int64_t>(shape.size()) - x.dim();
  SL_CHECK(lead >= 0, "expand: cannot expand ", x.describe(), " to ", shape_str(shape));
  Shape strides(shape.size(), 0);
  for (int64_t d = 0; d < x.dim(); ++d) {
    const int64_t s = x.shape()[d], t = shape[lead + d];
    SL_CHECK(s == t || s == 1, "expand: cannot expand ", x.describe(), " to ", shape_str(shape));
    strides[lead + d] = s == 1 && t != 1 ? 0 : x.strides()[d];
  }
  Tensor y = Tensor::make_view(x, shape, strides, x.offset());
  if (needs_grad({x})) {
    const Shape in_shape = x.shape();
    record("expand", {x}, {y}, [in_shape](const TensorList& g) { return TensorList{sum_to(g[0], in_shape)}; });
  }
  return y;
}

Tensor squeeze(const Tensor& x, int64_t dim) {
  const int64_t d = normalize_dim("squeeze", dim, x.dim());
  SL_CHECK(x.shape()[d] == 1, "squeeze: dim ", dim, " of ", x.describe(), " is not 1");
  Shape shape = x.shape(), strides = x.strides();
  shape.erase(shape.begin() + d);
  strides.erase(strides.begin() + d);
  Tensor y = Tensor::make_view(x, shape, strides, x.offset());
  if (needs_grad({x})) record("squeeze", {x}, {y}, [d](const TensorList& g) { return TensorList{unsqueeze(g[0], d)}; });
  return y;
}

Tensor unsqueeze(const Tensor& x, int64_t dim) {
  const int64_t d = normalize_dim("unsqueeze", dim, x.dim() + 1);
  Shape shape = x.shape(), strides = x.strides();
  const int64_t stride = d < x.dim() ? x.strides()[d] * x.shape()[d] : 1;
  shape.insert(shape.begin() + d, 1);
  strides.insert(strides.begin() + d, stride);
  Tensor y = Tensor::make_view(x, shape, strides, x.offset());
  if (needs_grad({x})) record("unsqueeze", {x}, {y}, [d](const TensorList& g) { return TensorList{squeeze(g[0], d)}; });
  return y;
}

}  // namespace sl
