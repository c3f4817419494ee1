// Fused elementwise kernels over broadcast operands (internal to autodiff ops).
//
// Contract: map_n(op, f, a, b, ...) returns a contiguous tensor of the broadcast shape and the
// operands' (common, floating) dtype with out[i] = f(a[i], b[i], ...). Operands may have any
// strides, including 0 for broadcast dims. f is a generic lambda called with scalar_t values.
#pragma once
#include <array>

#include "autodiff/strided.h"
#include "autodiff/tensor.h"

namespace sl::detail {

Shape broadcast_strides(const Tensor& t, const Shape& out_shape);
Shape broadcast_shapes_impl(const char* op, const Shape& a, const Shape& b);

template <class F, class... Ts>
Tensor map_n(const char* op, F&& f, const Ts&... ins) {
  constexpr size_t K = sizeof...(Ts);
  const std::array<const Tensor*, K> ts{&ins...};
  const DType dtype = ts[0]->dtype();
  Shape out_shape = ts[0]->shape();
  for (size_t k = 0; k < K; ++k) {
    SL_CHECK(ts[k]->dtype() == dtype, op, ": dtypes differ: ", ts[0]->describe(), " and ",
             ts[k]->describe(), " (convert with .to())");
    if (k) out_shape = broadcast_shapes_impl(op, out_shape, ts[k]->shape());
  }
  Tensor out = Tensor::empty(out_shape, dtype);
  SL_DISPATCH_FLOAT(dtype, op, [&] {
    using T = scalar_t;
    std::array<Shape, K + 1> strides;
    strides[0] = out.strides();
    std::array<const T*, K> base;
    for (size_t k = 0; k < K; ++k) {
      strides[k + 1] = broadcast_strides(*ts[k], out_shape);
      base[k] = ts[k]->template data<T>();
    }
    T* po = out.data<T>();
    for_each_strided<K + 1>(out_shape, strides, [&](const auto& off, int64_t n, const auto& st) {
      // A local copy: its captures (a slope, a scale) are then known not to alias the output,
      // so they stay in registers and the loops below vectorise, branches and all.
      const auto fn = f;
      T* o = po + off[0];
      bool unit = true;
      for (size_t k = 1; k <= K; ++k) unit = unit && st[k] == 1;
      if (unit) {
        [&]<size_t... I>(std::index_sequence<I...>) {
          const std::array<const T*, K> p{(base[I] + off[I + 1])...};
          for (int64_t i = 0; i < n; ++i) o[i] = static_cast<T>(fn(p[I][i]...));
        }(std::make_index_sequence<K>{});
      } else {
        [&]<size_t... I>(std::index_sequence<I...>) {
          const std::array<const T*, K> p{(base[I] + off[I + 1])...};
          for (int64_t i = 0; i < n; ++i) o[i] = static_cast<T>(fn(p[I][i * st[I + 1]]...));
        }(std::make_index_sequence<K>{});
      }
    });
  });
  return out;
}

}  // namespace sl::detail
