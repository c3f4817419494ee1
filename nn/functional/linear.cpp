#include "nn/functional/linear.h"

#include "autodiff/matmul.h"
#include "autodiff/tape.h"
#include "util/parallel.h"

namespace sl::nn {

// x is flattened to rows [R, in]; y = x · wᵀ, dx = dy · w, dw = dyᵀ · x, db = column sums of dy.
Tensor linear(const Tensor& x_in, const Tensor& w_in, const Tensor& b_in) {
  SL_CHECK(x_in.defined() && w_in.defined(), "linear: input and weight must be defined");
  SL_CHECK(w_in.dim() == 2, "linear: weight must be [out, in], got ", w_in.describe());
  SL_CHECK(x_in.dim() >= 1 && x_in.size(-1) == w_in.size(1), "linear: input ", shape_str(x_in.shape()),
           " has ", x_in.dim() >= 1 ? x_in.size(-1) : 0, " features, weight ", shape_str(w_in.shape()), " expects ",
           w_in.size(1));
  SL_CHECK(x_in.dtype() == w_in.dtype(), "linear: dtypes differ: input ", x_in.describe(), ", weight ",
           w_in.describe());
  if (b_in.defined())
    SL_CHECK(b_in.dim() == 1 && b_in.size(0) == w_in.size(0) && b_in.dtype() == x_in.dtype(), "linear: bias ",
             b_in.describe(), " must be [", w_in.size(0), "] of the input's dtype ", dtype_name(x_in.dtype()));
  const int64_t in = w_in.size(1), out = w_in.size(0);
  const int64_t rows = in > 0 ? x_in.numel() / in : shape_numel(Shape(x_in.shape().begin(), x_in.shape().end() - 1));
  Shape out_shape = x_in.shape();
  out_shape.back() = out;
  const Tensor x = x_in.detach().contiguous(), w = w_in.detach().contiguous();
  const Tensor b = b_in.defined() ? b_in.detach().contiguous() : Tensor();
  Tensor y = Tensor::empty(out_shape, x.dtype());
  SL_DISPATCH_FLOAT(x.dtype(), "linear", [&] {
    using T = scalar_t;
    T* py = y.data<T>();
    sl::detail::gemm<T>(false, true, rows, out, in, T(1), x.data<T>(), in, w.data<T>(), in, T(0), py, out);
    if (b.defined()) {
      const T* pb = b.data<T>();
      parallel_for(rows, 256, [&](int64_t r0, int64_t r1) {
        for (int64_t r = r0; r < r1; ++r)
          for (int64_t o = 0; o < out; ++o) py[r * out + o] += pb[o];
      });
    }
  });
  if (needs_grad({x_in, w_in, b_in})) {
    const bool gx = x_in.requires_grad(), gw = w_in.requires_grad(), gb = b.defined() && b_in.requires_grad();
    record("linear", {x_in, w_in, b_in}, {y}, [=](const TensorList& grads) {
      const Tensor dy = grads[0].contiguous();
      TensorList r(3);
      SL_DISPATCH_FLOAT(x.dtype(), "linear", [&] {
        using T = scalar_t;
        const T* pdy = dy.data<T>();
        if (gx) {
          r[0] = Tensor::empty(x.shape(), x.dtype());
          sl::detail::gemm<T>(false, false, rows, in, out, T(1), pdy, out, w.data<T>(), in, T(0), r[0].data<T>(), in);
        }
        if (gw) {
          r[1] = Tensor::empty(w.shape(), w.dtype());
          sl::detail::gemm<T>(true, false, out, in, rows, T(1), pdy, out, x.data<T>(), in, T(0), r[1].data<T>(), in);
        }
        if (gb) {
          r[2] = Tensor::empty(b.shape(), b.dtype());
          T* pdb = r[2].data<T>();
          parallel_for(out, 64, [&](int64_t o0, int64_t o1) {
            for (int64_t o = o0; o < o1; ++o) {
              double acc = 0;
              for (int64_t rr = 0; rr < rows; ++rr) acc += pdy[rr * out + o];
              pdb[o] = static_cast<T>(acc);
            }
          });
        }
      });
      return r;
    });
  }
  return y;
}

}  // namespace sl::nn
