#include "nn/functional/upsample.h"

#include <algorithm>
#include <array>
#include <vector>

#include "autodiff/tape.h"
#include "nn/functional/work_grain.h"
#include "util/parallel.h"

namespace sl::nn {
namespace {

// Along one axis, output index o reads input i0[o] with weight 1 - l1[o] and i1[o] with l1[o]
// (nearest: i1 = i0 and l1 = 0).
struct AxisMap {
  std::vector<int64_t> i0, i1;
  std::vector<double> l1;
};

AxisMap axis_map(int64_t in, int64_t scale, bool linear, bool align_corners) {
  const int64_t out = in * scale;
  AxisMap m;
  m.i0.resize(static_cast<size_t>(out));
  m.i1.resize(static_cast<size_t>(out));
  m.l1.assign(static_cast<size_t>(out), 0.0);
  for (int64_t o = 0; o < out; ++o) {
    if (!linear) {
      m.i0[o] = m.i1[o] = o / scale;
      continue;
    }
    double src;
    if (align_corners) {
      src = out > 1 ? static_cast<double>(o) * static_cast<double>(in - 1) / static_cast<double>(out - 1) : 0.0;
    } else {  // PyTorch with an explicit scale_factor: half-pixel centres, clamped at the first texel
      src = std::max((static_cast<double>(o) + 0.5) / static_cast<double>(scale) - 0.5, 0.0);
    }
    const int64_t i = std::min(static_cast<int64_t>(src), in - 1);
    m.i0[o] = i;
    m.i1[o] = std::min(i + 1, in - 1);
    m.l1[o] = src - static_cast<double>(i);
  }
  return m;
}

// One axis of a separable resampling. x is viewed as [outer, n_in, inner] (contiguous) and
// out[o][j][i] = (1 - l1[j])·x[o][i0[j]][i] + l1[j]·x[o][i1[j]][i]. Bilinear and trilinear
// interpolation are products of such 1-D weights, so resizing one axis at a time gives the same
// values with 2 taps per output and pass instead of 4 or 8, and every pass runs along
// contiguous memory.
template <class T>
void resample_axis(const T* x, T* out, int64_t outer, int64_t n_in, int64_t inner, const AxisMap& m) {
  const int64_t n_out = static_cast<int64_t>(m.i0.size());
  parallel_for(outer, detail::grain_for(n_out * inner), [&](int64_t o0, int64_t o1) {
    for (int64_t o = o0; o < o1; ++o)
      for (int64_t j = 0; j < n_out; ++j) {
        const T w1 = static_cast<T>(m.l1[j]), w0 = T(1) - w1;
        const T* a = x + (o * n_in + m.i0[j]) * inner;
        const T* b = x + (o * n_in + m.i1[j]) * inner;
        T* dst = out + (o * n_out + j) * inner;
        for (int64_t i = 0; i < inner; ++i) dst[i] = w0 * a[i] + w1 * b[i];
      }
  });
}

// The adjoint of resample_axis: gx[o][i0[j]] += (1 - l1[j])·g[o][j], gx[o][i1[j]] += l1[j]·g[o][j],
// with j in increasing order inside each outer slice, one slice per task: race-free and in a fixed
// order, so the result is the same for any thread count.
template <class T>
void resample_axis_backward(const T* g, T* gx, int64_t outer, int64_t n_in, int64_t inner, const AxisMap& m) {
  const int64_t n_out = static_cast<int64_t>(m.i0.size());
  std::fill(gx, gx + outer * n_in * inner, T(0));
  parallel_for(outer, detail::grain_for(n_out * inner), [&](int64_t o0, int64_t o1) {
    for (int64_t o = o0; o < o1; ++o)
      for (int64_t j = 0; j < n_out; ++j) {
        const T w1 = static_cast<T>(m.l1[j]), w0 = T(1) - w1;
        const T* src = g + (o * n_out + j) * inner;
        T* a = gx + (o * n_in + m.i0[j]) * inner;
        T* b = gx + (o * n_in + m.i1[j]) * inner;
        for (int64_t i = 0; i < inner; ++i) a[i] += w0 * src[i];
        if (w1 != T(0))
          for (int64_t i = 0; i < inner; ++i) b[i] += w1 * src[i];
      }
  });
}

// Shared by the four ops: the spatial axes are resized one at a time, last axis first.
template <size_t Dm>
Tensor upsample(const char* op, const Tensor& x_in, int64_t scale, bool linear, bool align_corners) {
  SL_CHECK(x_in.defined() && x_in.dim() == Dm + 2, op, ": input must be ", Dm + 2, "-d [N, C, ...], got ",
           x_in.defined() ? x_in.describe() : "undefined");
  SL_CHECK(scale >= 1, op, ": scale must be >= 1, got ", scale);
  SL_CHECK(x_in.dtype() != DType::I64, op, ": expected a floating tensor, got ", x_in.describe());
  const Tensor x = x_in.detach().contiguous();
  // shapes[k]: the tensor after resizing the last k spatial axes; maps[a]: spatial axis a.
  std::vector<Shape> shapes = {x.shape()};
  std::vector<AxisMap> maps(Dm);
  for (size_t k = 0; k < Dm; ++k) {
    const size_t axis = 2 + Dm - 1 - k;
    maps[axis - 2] = axis_map(x.size(static_cast<int64_t>(axis)), scale, linear, align_corners);
    Shape next = shapes.back();
    next[axis] *= scale;
    shapes.push_back(next);
  }
  // (outer, n_in, inner) of pass k, which resizes spatial axis Dm - 1 - k.
  auto view = [shapes](size_t k) {
    const Shape& s = shapes[k];
    const size_t axis = 2 + Dm - 1 - k;
    int64_t outer = 1, inner = 1;
    for (size_t d = 0; d < axis; ++d) outer *= s[d];
    for (size_t d = axis + 1; d < s.size(); ++d) inner *= s[d];
    return std::array<int64_t, 3>{outer, s[axis], inner};
  };
  Tensor y = x;
  SL_DISPATCH_FLOAT(x.dtype(), op, [&] {
    using T = scalar_t;
    for (size_t k = 0; k < Dm; ++k) {
      Tensor next = Tensor::empty(shapes[k + 1], x.dtype());
      const auto v = view(k);
      resample_axis<T>(y.data<T>(), next.data<T>(), v[0], v[1], v[2], maps[Dm - 1 - k]);
      y = next;
    }
  });
  if (needs_grad({x_in})) {
    record(op, {x_in}, {y}, [=](const TensorList& grads) {
      Tensor g = grads[0].contiguous();
      SL_DISPATCH_FLOAT(g.dtype(), op, [&] {
        using T = scalar_t;
        for (size_t k = Dm; k-- > 0;) {
          Tensor gx = Tensor::empty(shapes[k], g.dtype());
          const auto v = view(k);
          resample_axis_backward<T>(g.data<T>(), gx.data<T>(), v[0], v[1], v[2], maps[Dm - 1 - k]);
          g = gx;
        }
      });
      return TensorList{g};
    });
  }
  return y;
}

}  // namespace

Tensor upsample_nearest2d(const Tensor& x, int64_t scale) {
  return upsample<2>("upsample_nearest2d", x, scale, false, false);
}
Tensor upsample_bilinear2d(const Tensor& x, int64_t scale, bool align_corners) {
  return upsample<2>("upsample_bilinear2d", x, scale, true, align_corners);
}
Tensor upsample_nearest3d(const Tensor& x, int64_t scale) {
  return upsample<3>("upsample_nearest3d", x, scale, false, false);
}
Tensor upsample_trilinear3d(const Tensor& x, int64_t scale, bool align_corners) {
  return upsample<3>("upsample_trilinear3d", x, scale, true, align_corners);
}

}  // namespace sl::nn
