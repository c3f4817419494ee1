#include "autodiff/grid_sample.h"

#include <array>
#include <cmath>

#include "autodiff/tape.h"
#include "util/parallel.h"

namespace sl {
namespace {

// One sample point: for each spatial axis (input order, e.g. {H, W}) the lower texel index,
// the fractional weight of the upper texel and d(texel coordinate)/d(grid coordinate).
template <int Dm, class T>
struct Sample {
  std::array<int64_t, Dm> i0;
  std::array<T, Dm> frac;
  std::array<T, Dm> scale;
  bool valid;
};

template <int Dm, class T>
Sample<Dm, T> locate(const T* g, const std::array<int64_t, Dm>& size, bool align, GridPadding padding) {
  Sample<Dm, T> s;
  s.valid = true;
  for (int a = 0; a < Dm; ++a) {
    const T coord = g[Dm - 1 - a];  // grid (x, y, z) addresses the axes (W, H, D)
    const T n = static_cast<T>(size[a]);
    if (!std::isfinite(coord)) {
      s.valid = false;
      return s;
    }
    T c = align ? (coord + 1) / 2 * (n - 1) : ((coord + 1) * n - 1) / 2;
    T scale = align ? (n - 1) / 2 : n / 2;
    if (padding == GridPadding::Border) {
      if (c <= 0) {
        c = 0;
        scale = 0;
      } else if (c >= n - 1) {
        c = n - 1;
        scale = 0;
      }
    }
    const T f = std::floor(c);
    s.i0[a] = static_cast<int64_t>(f);
    s.frac[a] = c - f;
    s.scale[a] = scale;
  }
  return s;
}

template <int Dm>
struct Geometry {
  int64_t N, C, P;                 // batch, channels, output points per batch item
  std::array<int64_t, Dm> size;    // input spatial sizes
  std::array<int64_t, Dm> stride;  // input spatial strides (contiguous)
  int64_t plane;                   // elements per (n, c) input plane
};

// Visits the 2^Dm corners of a sample that lie inside the input: body(offset, weight, dweight[Dm]).
template <int Dm, class T, class Body>
void for_corners(const Sample<Dm, T>& s, const Geometry<Dm>& geo, Body&& body) {
  for (int corner = 0; corner < (1 << Dm); ++corner) {
    int64_t off = 0;
    bool inside = true;
    T w = 1;
    std::array<T, Dm> wa;
    for (int a = 0; a < Dm; ++a) {
      const bool up = (corner >> a) & 1;
      const int64_t i = s.i0[a] + (up ? 1 : 0);
      if (i < 0 || i >= geo.size[a]) {
        inside = false;
        break;
      }
      off += i * geo.stride[a];
      wa[a] = up ? s.frac[a] : 1 - s.frac[a];
      w *= wa[a];
    }
    if (!inside) continue;
    std::array<T, Dm> dw;  // d weight / d texel coordinate along each axis
    for (int a = 0; a < Dm; ++a) {
      T p = ((corner >> a) & 1) ? T(1) : T(-1);
      for (int b = 0; b < Dm; ++b)
        if (b != a) p *= wa[b];
      dw[a] = p;
    }
    body(off, w, dw);
  }
}

template <int Dm>
Tensor grid_sample_nd(const char* op, const Tensor& input_in, const Tensor& grid_in, bool align, GridPadding padding) {
  SL_CHECK(input_in.dim() == Dm + 2, op, ": input must be ", Dm + 2, "-d, got ", input_in.describe());
  SL_CHECK(grid_in.dim() == Dm + 2 && grid_in.size(-1) == Dm, op, ": grid must be [N, ..., ", Dm, "], got ",
           grid_in.describe());
  SL_CHECK(grid_in.size(0) == input_in.size(0), op, ": batch of input ", input_in.describe(), " and grid ",
           grid_in.describe(), " differ");
  SL_CHECK(input_in.dtype() == grid_in.dtype(), op, ": dtypes differ: ", input_in.describe(), " and ",
           grid_in.describe());
  const Tensor input = input_in.detach().contiguous();
  const Tensor grid = grid_in.detach().contiguous();
  Geometry<Dm> geo;
  geo.N = input.size(0);
  geo.C = input.size(1);
  geo.P = 1;
  for (int a = 0; a < Dm; ++a) geo.P *= grid.size(1 + a);
  geo.plane = 1;
  for (int a = Dm - 1; a >= 0; --a) {
    geo.size[a] = input.size(2 + a);
    geo.stride[a] = geo.plane;
    geo.plane *= geo.size[a];
  }
  Shape out_shape = {geo.N, geo.C};
  for (int a = 0; a < Dm; ++a) out_shape.push_back(grid.size(1 + a));
  Tensor out = Tensor::empty(out_shape, input.dtype());

  SL_DISPATCH_FLOAT(input.dtype(), op, [&] {
    using T = scalar_t;
    const T* pin = input.data<T>();
    const T* pg = grid.data<T>();
    T* po = out.data<T>();
    parallel_for(geo.N * geo.P, 256, [&](int64_t b, int64_t e) {
      for (int64_t q = b; q < e; ++q) {
        const int64_t n = q / geo.P, p = q % geo.P;
        const auto s = locate<Dm, T>(pg + q * Dm, geo.size, align, padding);
        for (int64_t c = 0; c < geo.C; ++c) {
          T acc = 0;
          if (s.valid) {
            const T* plane = pin + (n * geo.C + c) * geo.plane;
            for_corners<Dm, T>(s, geo, [&](int64_t off, T w, const auto&) { acc += w * plane[off]; });
          }
          po[(n * geo.C + c) * geo.P + p] = acc;
        }
      }
    });
  });

  if (needs_grad({input_in, grid_in})) {
    const bool g_in = input_in.requires_grad(), g_grid = grid_in.requires_grad();
    record(op, {input_in, grid_in}, {out}, [=](const TensorList& grads) {
      const Tensor gout = grads[0].contiguous();
      TensorList r(2);
      SL_DISPATCH_FLOAT(input.dtype(), op, [&] {
        using T = scalar_t;
        const T* pin = input.data<T>();
        const T* pg = grid.data<T>();
        const T* pgo = gout.data<T>();
        if (g_in) {  // one (n, c) plane per task: each plane is written by one thread, in point order
          Tensor gi = Tensor::zeros(input.shape(), input.dtype());
          T* pgi = gi.data<T>();
          parallel_for(geo.N * geo.C, 1, [&](int64_t b, int64_t e) {
            for (int64_t nc = b; nc < e; ++nc) {
              const int64_t n = nc / geo.C;
              T* plane = pgi + nc * geo.plane;
              const T* go = pgo + nc * geo.P;
              for (int64_t p = 0; p < geo.P; ++p) {
                const auto s = locate<Dm, T>(pg + (n * geo.P + p) * Dm, geo.size, align, padding);
                if (!s.valid) continue;
                for_corners<Dm, T>(s, geo, [&](int64_t off, T w, const auto&) { plane[off] += w * go[p]; });
              }
            }
          });
          r[0] = gi;
        }
        if (g_grid) {
          Tensor gg = Tensor::zeros(grid.shape(), grid.dtype());
          T* pgg = gg.data<T>();
          parallel_for(geo.N * geo.P, 256, [&](int64_t b, int64_t e) {
            for (int64_t q = b; q < e; ++q) {
              const int64_t n = q / geo.P, p = q % geo.P;
              const auto s = locate<Dm, T>(pg + q * Dm, geo.size, align, padding);
              if (!s.valid) continue;
              std::array<T, Dm> acc{};
              for (int64_t c = 0; c < geo.C; ++c) {
                const T* plane = pin + (n * geo.C + c) * geo.plane;
                const T go = pgo[(n * geo.C + c) * geo.P + p];
                for_corners<Dm, T>(s, geo, [&](int64_t off, T, const auto& dw) {
                  for (int a = 0; a < Dm; ++a) acc[a] += go * plane[off] * dw[a];
                });
              }
              for (int a = 0; a < Dm; ++a) pgg[q * Dm + (Dm - 1 - a)] = acc[a] * s.scale[a];
            }
          });
          r[1] = gg;
        }
      });
      return r;
    });
  }
  return out;
}

}  // namespace

Tensor grid_sample_2d(const Tensor& input, const Tensor& grid, bool align_corners, GridPadding padding) {
  return grid_sample_nd<2>("grid_sample_2d", input, grid, align_corners, padding);
}

Tensor grid_sample_3d(const Tensor& input, const Tensor& grid, bool align_corners, GridPadding padding) {
  return grid_sample_nd<3>("grid_sample_3d", input, grid, align_corners, padding);
}

}  // namespace sl
