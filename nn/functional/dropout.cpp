#include "nn/functional/dropout.h"

#include "autodiff/tape.h"
#include "util/parallel.h"
#include "util/random.h"

namespace sl::nn {

Tensor dropout(const Tensor& x_in, double p, bool training, uint64_t seed, uint64_t step) {
  SL_CHECK(x_in.defined(), "dropout: input is undefined");
  SL_CHECK(p >= 0.0 && p < 1.0, "dropout: p must be in [0, 1), got ", p, " for input ", x_in.describe());
  SL_CHECK(x_in.dtype() != DType::I64, "dropout: expected a floating tensor, got ", x_in.describe());
  if (!training || p == 0.0) return x_in;
  const Tensor x = x_in.detach().contiguous();
  // mask[i] = 1/(1-p) where kept, else 0; kept so that backward replays it exactly.
  Tensor mask = Tensor::empty(x.shape(), x.dtype());
  Tensor y = Tensor::empty(x.shape(), x.dtype());
  SL_DISPATCH_FLOAT(x.dtype(), "dropout", [&] {
    using T = scalar_t;
    const T keep_scale = static_cast<T>(1.0 / (1.0 - p));
    const T* px = x.data<T>();
    T* pm = mask.data<T>();
    T* py = y.data<T>();
    parallel_for(x.numel(), 16384, [&](int64_t i0, int64_t i1) {
      for (int64_t i = i0; i < i1; ++i) {
        pm[i] = uniform01(seed, step, static_cast<uint64_t>(i)) >= p ? keep_scale : T(0);
        py[i] = px[i] * pm[i];
      }
    });
  });
  if (needs_grad({x_in})) {
    record("dropout", {x_in}, {y}, [mask](const TensorList& grads) {
      const Tensor dy = grads[0].contiguous();
      Tensor dx = Tensor::empty(dy.shape(), dy.dtype());
      SL_DISPATCH_FLOAT(dy.dtype(), "dropout", [&] {
        using T = scalar_t;
        const T* pdy = dy.data<T>();
        const T* pm = mask.data<T>();
        T* pdx = dx.data<T>();
        parallel_for(dy.numel(), 16384, [&](int64_t i0, int64_t i1) {
          for (int64_t i = i0; i < i1; ++i) pdx[i] = pdy[i] * pm[i];
        });
      });
      return TensorList{dx};
    });
  }
  return y;
}

}  // namespace sl::nn
