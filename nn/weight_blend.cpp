#include "nn/weight_blend.h"

#include <cmath>
#include <cstdint>
#include <type_traits>

#include "util/error.h"

namespace sl::nn {
namespace {

// (1 − t)·a + t·b per element in double, rounded once to T (to nearest for integer T); the ends
// copy their side exactly.
template <class T>
void blend_values(const T* a, const T* b, T* out, int64_t n, double t) {
  for (int64_t i = 0; i < n; ++i) {
    if (t == 0.0 || t == 1.0) {
      out[i] = t == 0.0 ? a[i] : b[i];
      continue;
    }
    const double v = (1.0 - t) * static_cast<double>(a[i]) + t * static_cast<double>(b[i]);
    if constexpr (std::is_integral_v<T>)
      out[i] = static_cast<T>(std::llround(v));  // counters such as BatchNorm's num_batches_tracked
    else
      out[i] = static_cast<T>(v);
  }
}

template <class T>
void blend_tensor(const Tensor& a, const Tensor& b, const Tensor& out, double t) {
  blend_values(a.data<T>(), b.data<T>(), out.data<T>(), a.numel(), t);
}

}  // namespace

StateDict blend_states(const StateDict& a, const StateDict& b, double t) {
  SL_CHECK(std::isfinite(t) && t >= 0.0 && t <= 1.0, "blend weight t must be in [0, 1], got ", t);
  const StateMismatch mismatch = compare_state(a, b);
  SL_CHECK(mismatch.empty(), "cannot blend two states that differ: ", mismatch.message());
  StateDict out;
  for (const auto& [name, ta] : a) {
    const Tensor ca = ta.contiguous(), cb = b.at(name).contiguous();
    Tensor r = Tensor::empty(ta.shape(), ta.dtype());
    switch (ta.dtype()) {
      case DType::F32: blend_tensor<float>(ca, cb, r, t); break;
      case DType::F64: blend_tensor<double>(ca, cb, r, t); break;
      case DType::I64: blend_tensor<int64_t>(ca, cb, r, t); break;
    }
    out.emplace(name, std::move(r));
  }
  return out;
}

}  // namespace sl::nn
