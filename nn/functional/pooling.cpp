#include "nn/functional/pooling.h"

#include <cmath>
#include <limits>
#include <vector>

#include "autodiff/tape.h"
#include "nn/functional/work_grain.h"
#include "util/parallel.h"

namespace sl::nn {
namespace {

// A pooling window in 3 spatial dims; 2-D pooling uses depth 1 with a kernel depth of 1.
struct PoolGeometry {
  int64_t planes = 0;  // N·C
  std::array<int64_t, 3> in{}, out{}, k{}, stride{}, pad{};
  int64_t in_plane() const { return in[0] * in[1] * in[2]; }
  int64_t out_plane() const { return out[0] * out[1] * out[2]; }
};

template <size_t Dm>
PoolGeometry pool_geometry(const char* op, const Tensor& x, const std::array<int64_t, Dm>& kernel,
                           const std::array<int64_t, Dm>& stride, const std::array<int64_t, Dm>& padding) {
  SL_CHECK(x.defined() && x.dim() == Dm + 2, op, ": input must be ", Dm + 2, "-d [N, C, ...], got ",
           x.defined() ? x.describe() : "undefined");
  PoolGeometry g;
  g.planes = x.size(0) * x.size(1);
  for (int a = 0; a < 3; ++a) g.in[a] = g.out[a] = g.k[a] = g.stride[a] = 1, g.pad[a] = 0;
  for (size_t a = 0; a < Dm; ++a) {
    const size_t s = 3 - Dm + a;
    SL_CHECK(kernel[a] >= 1 && stride[a] >= 1 && padding[a] >= 0 && 2 * padding[a] <= kernel[a], op,
             ": need kernel >= 1, stride >= 1 and 0 <= padding <= kernel / 2, got kernel ", kernel[a], ", stride ",
             stride[a], ", padding ", padding[a], " for input ", shape_str(x.shape()));
    g.in[s] = x.size(2 + a);
    g.k[s] = kernel[a];
    g.stride[s] = stride[a];
    g.pad[s] = padding[a];
    const int64_t span = g.in[s] + 2 * g.pad[s] - g.k[s];
    SL_CHECK(span >= 0, op, ": kernel ", kernel[a], " is larger than the padded input ", shape_str(x.shape()));
    g.out[s] = span / g.stride[s] + 1;
  }
  return g;
}

Shape pooled_shape(const Tensor& x, const PoolGeometry& g, size_t dims) {
  Shape s = {x.size(0), x.size(1)};
  for (size_t a = 3 - dims; a < 3; ++a) s.push_back(g.out[a]);
  return s;
}

// Calls f(input offset) for every in-bounds tap of the window of output position (z, y, x),
// in scan order (z, then y, then x). The in-bounds tap ranges are computed once per window
// rather than tested per tap.
template <class F>
inline void for_window(const PoolGeometry& g, int64_t z, int64_t y, int64_t x, F&& f) {
  const int64_t z0 = z * g.stride[0] - g.pad[0], y0 = y * g.stride[1] - g.pad[1], x0 = x * g.stride[2] - g.pad[2];
  const int64_t kz1 = std::min(g.k[0], g.in[0] - z0), ky1 = std::min(g.k[1], g.in[1] - y0);
  const int64_t kx0 = std::max<int64_t>(0, -x0), kx1 = std::min(g.k[2], g.in[2] - x0);
  for (int64_t kz = std::max<int64_t>(0, -z0); kz < kz1; ++kz)
    for (int64_t ky = std::max<int64_t>(0, -y0); ky < ky1; ++ky) {
      const int64_t row = ((z0 + kz) * g.in[1] + y0 + ky) * g.in[2] + x0;
      for (int64_t kx = kx0; kx < kx1; ++kx) f(row + kx);
    }
}

// Visits every output position of one plane: f(output index, z, y, x).
template <class F>
inline void for_outputs(const PoolGeometry& g, F&& f) {
  int64_t o = 0;
  for (int64_t z = 0; z < g.out[0]; ++z)
    for (int64_t y = 0; y < g.out[1]; ++y)
      for (int64_t x = 0; x < g.out[2]; ++x) f(o++, z, y, x);
}

// The max-pooling rule for one more tap v at input offset i: taken when larger, or NaN (as in
// PyTorch, so a NaN input is never dropped); a NaN maximum is kept (best == best is false for
// NaN); ties keep the earlier tap. Selects, not branches: which tap wins is data-dependent.
template <class T>
inline void max_pool_take(T v, int64_t i, T& best, int64_t& at) {
  const bool take = (best == best) & !(v <= best);
  best = take ? v : best;
  at = take ? i : at;
}

// One plane of max pooling: out[o] and the input offset of its winner, argmax[o]. Every output
// visits its taps in scan order (z, y, x). The outputs of a row whose windows lie inside the
// row's x range take each tap for the whole run of outputs at once (a loop the compiler
// vectorises); the few outputs at the x borders go through for_window.
template <class T>
void max_pool_plane(const PoolGeometry& g, const T* plane, T* out, int64_t* argmax) {
  const int64_t s = g.stride[2], pad = g.pad[2];
  const int64_t x_lo = std::min(g.out[2], (pad + s - 1) / s);  // first x with x·s - pad >= 0
  const int64_t span = g.in[2] - g.k[2] + pad;  // last x with x·s - pad + k <= in is span / s
  const int64_t x_hi = span < 0 ? x_lo : std::max(x_lo, std::min(g.out[2], span / s + 1));
  auto generic = [&](int64_t o, int64_t z, int64_t yy, int64_t xx) {
    T best = -std::numeric_limits<T>::infinity();
    int64_t at = -1;
    for_window(g, z, yy, xx, [&](int64_t i) {
      if (at < 0) best = plane[i], at = i;
      else max_pool_take(plane[i], i, best, at);
    });
    out[o] = best;
    argmax[o] = at;
  };
  for (int64_t z = 0; z < g.out[0]; ++z)
    for (int64_t yy = 0; yy < g.out[1]; ++yy) {
      const int64_t row_o = (z * g.out[1] + yy) * g.out[2];
      for (int64_t xx = 0; xx < x_lo; ++xx) generic(row_o + xx, z, yy, xx);
      for (int64_t xx = x_hi; xx < g.out[2]; ++xx) generic(row_o + xx, z, yy, xx);
      if (x_hi <= x_lo) continue;
      const int64_t z0 = z * g.stride[0] - g.pad[0], y0 = yy * g.stride[1] - g.pad[1];
      const int64_t kz0 = std::max<int64_t>(0, -z0), kz1 = std::min(g.k[0], g.in[0] - z0);
      const int64_t ky0 = std::max<int64_t>(0, -y0), ky1 = std::min(g.k[1], g.in[1] - y0);
      T* best = out + row_o;
      int64_t* at = argmax + row_o;
      bool first = true;
      for (int64_t kz = kz0; kz < kz1; ++kz)
        for (int64_t ky = ky0; ky < ky1; ++ky)
          for (int64_t kx = 0; kx < g.k[2]; ++kx) {
            const int64_t tap = ((z0 + kz) * g.in[1] + y0 + ky) * g.in[2] - pad + kx;  // offset of x = 0
            if (first) {
              for (int64_t xx = x_lo; xx < x_hi; ++xx) best[xx] = plane[tap + xx * s], at[xx] = tap + xx * s;
              first = false;
            } else {
              for (int64_t xx = x_lo; xx < x_hi; ++xx) max_pool_take(plane[tap + xx * s], tap + xx * s, best[xx], at[xx]);
            }
          }
    }
}

template <size_t Dm>
Tensor max_pool(const char* op, const Tensor& x_in, const std::array<int64_t, Dm>& kernel,
                const std::array<int64_t, Dm>& stride, const std::array<int64_t, Dm>& padding) {
  const PoolGeometry g = pool_geometry<Dm>(op, x_in, kernel, stride, padding);
  const Tensor x = x_in.detach().contiguous();
  Tensor y = Tensor::empty(pooled_shape(x, g, Dm), x.dtype());
  // argmax[o]: offset in its input plane of the element that won output o (for backward). A
  // tensor, not a vector: its buffer is reused from step to step and never zero-filled.
  const Tensor argmax = Tensor::empty(y.shape(), DType::I64);
  SL_DISPATCH_FLOAT(x.dtype(), op, [&] {
    using T = scalar_t;
    const T* px = x.data<T>();
    T* py = y.data<T>();
    int64_t* pa = argmax.data<int64_t>();
    parallel_for(g.planes, detail::grain_for(g.out_plane() * g.k[0] * g.k[1] * g.k[2]), [&](int64_t p0, int64_t p1) {
      for (int64_t p = p0; p < p1; ++p)
        max_pool_plane(g, px + p * g.in_plane(), py + p * g.out_plane(), pa + p * g.out_plane());
    });
  });
  if (needs_grad({x_in})) {
    const Shape xs = x.shape();
    const DType dt = x.dtype();
    record(op, {x_in}, {y}, [=](const TensorList& grads) {
      const Tensor gy = grads[0].contiguous();
      Tensor gx = Tensor::zeros(xs, dt);
      SL_DISPATCH_FLOAT(dt, op, [&] {
        using T = scalar_t;
        const T* pg = gy.data<T>();
        T* pgx = gx.data<T>();
        const int64_t* pa = argmax.data<int64_t>();
        parallel_for(g.planes, detail::grain_for(g.out_plane() * g.k[0] * g.k[1] * g.k[2]), [&](int64_t p0, int64_t p1) {
          for (int64_t p = p0; p < p1; ++p)
            for (int64_t o = 0; o < g.out_plane(); ++o) {
              const int64_t q = p * g.out_plane() + o;
              if (pa[q] >= 0) pgx[p * g.in_plane() + pa[q]] += pg[q];
            }
        });
      });
      return TensorList{gx};
    });
  }
  return y;
}

template <size_t Dm>
Tensor avg_pool(const char* op, const Tensor& x_in, const std::array<int64_t, Dm>& kernel,
                const std::array<int64_t, Dm>& stride, const std::array<int64_t, Dm>& padding) {
  const PoolGeometry g = pool_geometry<Dm>(op, x_in, kernel, stride, padding);
  const Tensor x = x_in.detach().contiguous();
  Tensor y = Tensor::empty(pooled_shape(x, g, Dm), x.dtype());
  const double inv_volume = 1.0 / static_cast<double>(g.k[0] * g.k[1] * g.k[2]);  // count_include_pad
  SL_DISPATCH_FLOAT(x.dtype(), op, [&] {
    using T = scalar_t;
    const T* px = x.data<T>();
    T* py = y.data<T>();
    parallel_for(g.planes, detail::grain_for(g.out_plane() * g.k[0] * g.k[1] * g.k[2]), [&](int64_t p0, int64_t p1) {
      for (int64_t p = p0; p < p1; ++p) {
        const T* plane = px + p * g.in_plane();
        for_outputs(g, [&](int64_t o, int64_t z, int64_t yy, int64_t xx) {
          T acc = 0;
          for_window(g, z, yy, xx, [&](int64_t i) { acc += plane[i]; });
          py[p * g.out_plane() + o] = acc * static_cast<T>(inv_volume);
        });
      }
    });
  });
  if (needs_grad({x_in})) {
    const Shape xs = x.shape();
    const DType dt = x.dtype();
    record(op, {x_in}, {y}, [=](const TensorList& grads) {
      const Tensor gy = grads[0].contiguous();
      Tensor gx = Tensor::zeros(xs, dt);
      SL_DISPATCH_FLOAT(dt, op, [&] {
        using T = scalar_t;
        const T* pg = gy.data<T>();
        T* pgx = gx.data<T>();
        parallel_for(g.planes, detail::grain_for(g.out_plane() * g.k[0] * g.k[1] * g.k[2]), [&](int64_t p0, int64_t p1) {
          for (int64_t p = p0; p < p1; ++p) {
            T* plane = pgx + p * g.in_plane();
            for_outputs(g, [&](int64_t o, int64_t z, int64_t yy, int64_t xx) {
              const T v = pg[p * g.out_plane() + o] * static_cast<T>(inv_volume);
              for_window(g, z, yy, xx, [&](int64_t i) { plane[i] += v; });
            });
          }
        });
      });
      return TensorList{gx};
    });
  }
  return y;
}

}  // namespace

Tensor max_pool2d(const Tensor& x, std::array<int64_t, 2> kernel, std::array<int64_t, 2> stride,
                  std::array<int64_t, 2> padding) {
  return max_pool<2>("max_pool2d", x, kernel, stride, padding);
}
Tensor avg_pool2d(const Tensor& x, std::array<int64_t, 2> kernel, std::array<int64_t, 2> stride,
                  std::array<int64_t, 2> padding) {
  return avg_pool<2>("avg_pool2d", x, kernel, stride, padding);
}
Tensor max_pool3d(const Tensor& x, std::array<int64_t, 3> kernel, std::array<int64_t, 3> stride,
                  std::array<int64_t, 3> padding) {
  return max_pool<3>("max_pool3d", x, kernel, stride, padding);
}
Tensor avg_pool3d(const Tensor& x, std::array<int64_t, 3> kernel, std::array<int64_t, 3> stride,
                  std::array<int64_t, 3> padding) {
  return avg_pool<3>("avg_pool3d", x, kernel, stride, padding);
}

// The mean over the spatial axes: a [N, C, S] view reduced over S, with its own node so the
// backward is one broadcast rather than a chain of reshapes.
Tensor global_avg_pool(const Tensor& x_in) {
  SL_CHECK(x_in.defined() && x_in.dim() >= 3, "global_avg_pool: input must be [N, C, ...] with at least one ",
           "spatial dim, got ", x_in.defined() ? x_in.describe() : "undefined");
  const int64_t N = x_in.size(0), C = x_in.size(1), S = x_in.numel() / std::max<int64_t>(N * C, 1);
  SL_CHECK(S > 0, "global_avg_pool: input ", x_in.describe(), " has no spatial positions");
  const Tensor x = x_in.detach().contiguous();
  Tensor y = Tensor::empty({N, C}, x.dtype());
  SL_DISPATCH_FLOAT(x.dtype(), "global_avg_pool", [&] {
    using T = scalar_t;
    const T* px = x.data<T>();
    T* py = y.data<T>();
    parallel_for(N * C, detail::grain_for(S), [&](int64_t p0, int64_t p1) {
      for (int64_t p = p0; p < p1; ++p) {
        double acc = 0;
        for (int64_t s = 0; s < S; ++s) acc += px[p * S + s];
        py[p] = static_cast<T>(acc / static_cast<double>(S));
      }
    });
  });
  if (needs_grad({x_in})) {
    const Shape xs = x.shape();
    record("global_avg_pool", {x_in}, {y}, [=](const TensorList& grads) {
      const Tensor gy = grads[0].contiguous();
      Tensor gx = Tensor::empty(xs, gy.dtype());
      SL_DISPATCH_FLOAT(gy.dtype(), "global_avg_pool", [&] {
        using T = scalar_t;
        const T* pg = gy.data<T>();
        T* pgx = gx.data<T>();
        const T inv = static_cast<T>(1.0 / static_cast<double>(S));
        parallel_for(N * C, detail::grain_for(S), [&](int64_t p0, int64_t p1) {
          for (int64_t p = p0; p < p1; ++p)
            for (int64_t s = 0; s < S; ++s) pgx[p * S + s] = pg[p] * inv;
        });
      });
      return TensorList{gx};
    });
  }
  return y;
}

}  // namespace sl::nn
