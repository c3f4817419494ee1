#include "render/insertion_ops.h"

#include "autodiff/tape.h"
#include "util/parallel.h"

namespace sl::render {
namespace {

void check_offsets(const char* op, const std::vector<int64_t>& o, int64_t rows) {
  SL_CHECK(!o.empty() && o.front() == 0 && o.back() == rows, op, ": offsets must run from 0 to ", rows, ", got ",
           o.empty() ? -1 : o.front(), "..", o.empty() ? -1 : o.back());
  for (size_t i = 1; i < o.size(); ++i) SL_CHECK(o[i] >= o[i - 1], op, ": offsets decrease at ", i);
}

}  // namespace

Tensor weighted_segment_sum(const Tensor& values, const Tensor& weights, const std::vector<int64_t>& offsets) {
  SL_CHECK(values.dim() == 2 && values.size(1) == 3 && weights.shape() == values.shape(),
           "weighted_segment_sum: values ", values.describe(), " and weights ", weights.describe(), " must be [R, 3]");
  SL_CHECK(values.dtype() == weights.dtype(), "weighted_segment_sum: dtypes differ: ", values.describe(), ", ",
           weights.describe());
  check_offsets("weighted_segment_sum", offsets, values.size(0));
  const int64_t P = int64_t(offsets.size()) - 1;
  const Tensor v = values.detach().contiguous(), w = weights.detach().contiguous();
  Tensor out = Tensor::zeros({P, 3}, values.dtype());
  SL_DISPATCH_FLOAT(values.dtype(), "weighted_segment_sum", [&] {
    using T = scalar_t;
    const T *pv = v.data<T>(), *pw = w.data<T>();
    T* po = out.data<T>();
    parallel_for(P, 256, [&](int64_t b, int64_t e) {
      for (int64_t p = b; p < e; ++p)
        for (int64_t r = offsets[p]; r < offsets[p + 1]; ++r)
          for (int c = 0; c < 3; ++c) po[3 * p + c] += pw[3 * r + c] * pv[3 * r + c];
    });
  });
  if (needs_grad({values})) {
    record("weighted_segment_sum", {values}, {out}, [w, offsets](const TensorList& g) {
      const Tensor go = g[0].contiguous();
      const int64_t R = offsets.back(), P = int64_t(offsets.size()) - 1;
      Tensor gv = Tensor::empty({R, 3}, go.dtype());
      SL_DISPATCH_FLOAT(go.dtype(), "weighted_segment_sum", [&] {
        using T = scalar_t;
        const T *pg = go.data<T>(), *pw = w.data<T>();
        T* pr = gv.data<T>();
        parallel_for(P, 256, [&](int64_t b, int64_t e) {
          for (int64_t p = b; p < e; ++p)
            for (int64_t r = offsets[p]; r < offsets[p + 1]; ++r)
              for (int c = 0; c < 3; ++c) pr[3 * r + c] = pw[3 * r + c] * pg[3 * p + c];
        });
      });
      return TensorList{gv};
    });
  }
  return out;
}

Tensor shadow_ratio(const Tensor& radiance, const std::vector<double>& weights, const std::vector<double>& visibility,
                    const std::vector<int64_t>& offsets, double epsilon) {
  SL_CHECK(radiance.dim() == 2 && radiance.size(1) == 3, "shadow_ratio: radiance must be [R, 3], got ",
           radiance.describe());
  SL_CHECK(int64_t(visibility.size()) == radiance.size(0) && visibility.size() == weights.size(), "shadow_ratio: ",
           visibility.size(), " visibilities and ", weights.size(), " weights for ", radiance.describe());
  SL_CHECK(epsilon > 0, "shadow_ratio: epsilon must be > 0, got ", epsilon);
  check_offsets("shadow_ratio", offsets, radiance.size(0));
  const int64_t P = int64_t(offsets.size()) - 1;
  const Tensor L = radiance.detach().contiguous();
  Tensor S = Tensor::empty({P, 3}, radiance.dtype());
  Tensor denom = Tensor::empty({P, 3}, radiance.dtype());
  SL_DISPATCH_FLOAT(radiance.dtype(), "shadow_ratio", [&] {
    using T = scalar_t;
    const T* pl = L.data<T>();
    T *ps = S.data<T>(), *pd = denom.data<T>();
    parallel_for(P, 256, [&](int64_t b, int64_t e) {
      for (int64_t p = b; p < e; ++p)
        for (int c = 0; c < 3; ++c) {
          double num = epsilon, den = epsilon;
          for (int64_t r = offsets[p]; r < offsets[p + 1]; ++r) {
            num += visibility[r] * weights[r] * pl[3 * r + c];
            den += weights[r] * pl[3 * r + c];
          }
          ps[3 * p + c] = T(num / den);
          pd[3 * p + c] = T(den);
        }
    });
  });
  if (needs_grad({radiance})) {
    const Tensor Sd = S.detach();
    record("shadow_ratio", {radiance}, {S}, [Sd, denom, weights, visibility, offsets](const TensorList& g) {
      const Tensor go = g[0].contiguous();
      const int64_t R = offsets.back(), P = int64_t(offsets.size()) - 1;
      Tensor gl = Tensor::empty({R, 3}, go.dtype());
      SL_DISPATCH_FLOAT(go.dtype(), "shadow_ratio", [&] {
        using T = scalar_t;
        const T *pg = go.data<T>(), *ps = Sd.data<T>(), *pd = denom.data<T>();
        T* pr = gl.data<T>();
        parallel_for(P, 256, [&](int64_t b, int64_t e) {
          for (int64_t p = b; p < e; ++p)
            for (int64_t r = offsets[p]; r < offsets[p + 1]; ++r)
              for (int c = 0; c < 3; ++c)
                pr[3 * r + c] = pg[3 * p + c] * T(weights[r]) * (T(visibility[r]) - ps[3 * p + c]) / pd[3 * p + c];
        });
      });
      return TensorList{gl};
    });
  }
  return S;
}

}  // namespace sl::render
