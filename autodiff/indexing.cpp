#include "autodiff/indexing.h"

#include "autodiff/shape_ops.h"
#include "autodiff/tape.h"
#include "util/parallel.h"

namespace sl {
namespace {

void check_index_tensor(const char* op, const Tensor& index) {
  SL_CHECK(index.dtype() == DType::I64, op, ": index must be i64, got ", index.describe());
}

// Multi-index walk over `shape` (row-major), giving each operand's element offset.
struct OffsetWalker {
  Shape shape;
  std::vector<Shape> strides;
  std::vector<int64_t> coord;
  std::vector<int64_t> off;
  OffsetWalker(Shape s, std::vector<Shape> st) : shape(std::move(s)), strides(std::move(st)) {
    coord.assign(shape.size(), 0);
    off.assign(strides.size(), 0);
  }
  void next() {
    for (size_t d = shape.size(); d-- > 0;) {
      ++coord[d];
      for (size_t k = 0; k < strides.size(); ++k) off[k] += strides[k][d];
      if (coord[d] < shape[d]) return;
      for (size_t k = 0; k < strides.size(); ++k) off[k] -= strides[k][d] * shape[d];
      coord[d] = 0;
    }
  }
};

// out[.., i, ..] += src[.., j, ..] at i = index[.., j, ..] along dim (scatter) or
// out[.., j, ..] = src[.., index[.., j, ..], ..] (gather). Parallel over the outermost dim when
// it is not `dim`, so no two threads write the same element; each row runs in index order.
template <bool Scatter>
void gather_scatter(const char* op, const Tensor& out, const Tensor& src, int64_t dim, const Tensor& index) {
  const Tensor idx = index.contiguous();
  const int64_t* pi = idx.data<int64_t>();
  const int64_t limit = Scatter ? out.shape()[dim] : src.shape()[dim];
  const Shape& ishape = idx.shape();
  // Validate before the parallel loop: an exception must never leave an OpenMP region.
  for (int64_t e = 0, n = idx.numel(); e < n; ++e)
    SL_CHECK(pi[e] >= 0 && pi[e] < limit, op, ": index ", pi[e], " is out of range for dim ", dim, " of size ", limit);
  SL_DISPATCH_FLOAT(out.dtype(), op, [&] {
    using T = scalar_t;
    T* po = out.data<T>();
    const T* ps = src.data<T>();
    // Strides: index (contiguous), out, src; the `dim` coordinate is replaced by the index value.
    Shape so = out.strides(), ss = src.strides(), si = contiguous_strides(ishape);
    auto run_rows = [&](int64_t lo, int64_t hi) {
      Shape sub = ishape;
      int64_t base_i = 0, base_o = 0, base_s = 0;
      if (!ishape.empty() && dim != 0) {
        sub[0] = hi - lo;
        base_i = lo * si[0];
        base_o = lo * so[0];
        base_s = lo * ss[0];
      }
      Shape so_d = so, ss_d = ss;
      (Scatter ? so_d : ss_d)[dim] = 0;  // the indexed side moves by index value, not by coord
      OffsetWalker w(sub, {si, so_d, ss_d});
      const int64_t n = shape_numel(sub);
      for (int64_t e = 0; e < n; ++e, w.next()) {
        const int64_t j = pi[base_i + w.off[0]];
        if (Scatter) po[base_o + w.off[1] + j * so[dim]] += ps[base_s + w.off[2]];
        else po[base_o + w.off[1]] = ps[base_s + w.off[2] + j * ss[dim]];
      }
    };
    if (ishape.empty() || dim == 0 || ishape[0] < 2) {
      run_rows(0, ishape.empty() ? 1 : ishape[0]);
    } else {
      parallel_for(ishape[0], 1, run_rows);
    }
  });
}

void check_gather_shapes(const char* op, const Tensor& x, int64_t dim, const Tensor& index, const Tensor* src) {
  SL_CHECK(index.dim() == x.dim(), op, ": index ", index.describe(), " must have the rank of ", x.describe());
  for (int64_t d = 0; d < x.dim(); ++d) {
    if (d != dim)
      SL_CHECK(index.shape()[d] <= x.shape()[d], op, ": index ", index.describe(), " exceeds ", x.describe(),
               " in dim ", d);
    if (src) SL_CHECK(index.shape()[d] <= src->shape()[d], op, ": index ", index.describe(), " exceeds src ",
                      src->describe(), " in dim ", d);
  }
}

}  // namespace

Tensor gather(const Tensor& x, int64_t dim, const Tensor& index) {
  check_index_tensor("gather", index);
  const int64_t d = normalize_dim("gather", dim, x.dim());
  check_gather_shapes("gather", x, d, index, nullptr);
  Tensor y = Tensor::empty(index.shape(), x.dtype());
  gather_scatter<false>("gather", y, x, d, index);
  if (needs_grad({x})) {
    const Shape in_shape = x.shape();
    const Tensor idx = index;
    record("gather", {x}, {y}, [=](const TensorList& g) {
      return TensorList{scatter_add(Tensor::zeros(in_shape, g[0].dtype()), d, idx, g[0])};
    });
  }
  return y;
}

Tensor scatter_add(const Tensor& x, int64_t dim, const Tensor& index, const Tensor& src) {
  check_index_tensor("scatter_add", index);
  SL_CHECK(x.dtype() == src.dtype(), "scatter_add: dtypes differ: ", x.describe(), " and ", src.describe());
  const int64_t d = normalize_dim("scatter_add", dim, x.dim());
  check_gather_shapes("scatter_add", x, d, index, &src);
  Tensor y = x.detach().clone();
  gather_scatter<true>("scatter_add", y, src, d, index);
  if (needs_grad({x, src})) {
    const Tensor idx = index;
    const Shape src_shape = src.shape();
    record("scatter_add", {x, src}, {y}, [=](const TensorList& g) {
      Tensor gs = gather(g[0], d, idx);
      if (gs.shape() != src_shape) {
        std::vector<std::pair<int64_t, int64_t>> pads;
        for (size_t k = 0; k < src_shape.size(); ++k) pads.push_back({0, src_shape[k] - gs.shape()[k]});
        gs = pad(gs, pads);
      }
      return TensorList{g[0], gs};
    });
  }
  return y;
}

Tensor index_select(const Tensor& x, int64_t dim, const Tensor& index) {
  check_index_tensor("index_select", index);
  SL_CHECK(index.dim() == 1, "index_select: index must be 1-d, got ", index.describe());
  const int64_t d = normalize_dim("index_select", dim, x.dim());
  // index_select == gather with the index broadcast along every other dim.
  Shape ishape = x.shape();
  ishape[d] = index.numel();
  Shape view_shape(x.dim(), 1);
  view_shape[d] = index.numel();
  Tensor full_index;
  {
    NoGradGuard no_grad;
    full_index = expand(reshape(index, view_shape), ishape).contiguous();
  }
  return gather(x, d, full_index);
}

}  // namespace sl
