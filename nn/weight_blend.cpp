#include "nn/weight_blend.h"

#include <cmath>

#include "util/error.h"

namespace sl::nn {

StateDict blend_states(const StateDict& a, const StateDict& b, double t) {
  SL_CHECK(std::isfinite(t) && t >= 0.0 && t <= 1.0, "blend weight t must be in [0, 1], got ", t);
  const StateMismatch mismatch = compare_state(a, b);
  SL_CHECK(mismatch.empty(), "cannot blend two states that differ: ", mismatch.message());
  StateDict out;
  for (const auto& [name, ta] : a) {
    const Tensor& tb = b.at(name);
    const Tensor ca = ta.contiguous(), cb = tb.contiguous();
    Tensor r = Tensor::empty(ta.shape(), ta.dtype());
    const int64_t n = ta.numel();
    switch (ta.dtype()) {
      case DType::F32: {
        const float *pa = ca.data<float>(), *pb = cb.data<float>();
        float* pr = r.data<float>();
        for (int64_t i = 0; i < n; ++i)
          pr[i] = t == 0.0 ? pa[i] : t == 1.0 ? pb[i]
                                              : static_cast<float>((1.0 - t) * pa[i] + t * static_cast<double>(pb[i]));
        break;
      }
      case DType::F64: {
        const double *pa = ca.data<double>(), *pb = cb.data<double>();
        double* pr = r.data<double>();
        for (int64_t i = 0; i < n; ++i) pr[i] = t == 0.0 ? pa[i] : t == 1.0 ? pb[i] : (1.0 - t) * pa[i] + t * pb[i];
        break;
      }
      case DType::I64: {  // counters such as BatchNorm's num_batches_tracked: rounded to nearest
        const int64_t *pa = ca.data<int64_t>(), *pb = cb.data<int64_t>();
        int64_t* pr = r.data<int64_t>();
        for (int64_t i = 0; i < n; ++i)
          pr[i] = t == 0.0 ? pa[i] : t == 1.0 ? pb[i]
                                              : std::llround((1.0 - t) * static_cast<double>(pa[i]) + t * static_cast<double>(pb[i]));
        break;
      }
    }
    out.emplace(name, std::move(r));
  }
  return out;
}

}  // namespace sl::nn
