#include "nn/functional/depthwise_conv.h"

#include <algorithm>
#include <vector>

#include "autodiff/tape.h"
#include "nn/functional/work_grain.h"
#include "util/parallel.h"

namespace sl::nn {
namespace {

// One (n, c) plane and its zero-padded copy. Each padded row of Wp = W + 2·pw columns is stored
// as its sw column phases of `phase_len` entries each (padded column m at phase m % sw, index
// m / sw), so tap (u, v) of the outputs j = 0 .. Wo − 1 of row i is one contiguous run.
struct Plane {
  int64_t H, W, kh, kw, sh, sw, ph, pw, Ho, Wo;
  int64_t Hp, Wp, phase_len;

  Plane(int64_t H_, int64_t W_, int64_t kh_, int64_t kw_, int64_t sh_, int64_t sw_, int64_t ph_, int64_t pw_)
      : H(H_), W(W_), kh(kh_), kw(kw_), sh(sh_), sw(sw_), ph(ph_), pw(pw_) {
    Ho = (H + 2 * ph - kh) / sh + 1;
    Wo = (W + 2 * pw - kw) / sw + 1;
    Hp = H + 2 * ph;
    Wp = W + 2 * pw;
    phase_len = (Wp + sw - 1) / sw;
  }
  int64_t taps() const { return kh * kw; }
  int64_t pitch() const { return sw * phase_len; }
  int64_t padded_size() const { return Hp * pitch(); }
  int64_t in_size() const { return H * W; }
  int64_t out_size() const { return Ho * Wo; }
  // Padded element (row r, column m) in the phase layout.
  int64_t padded_at(int64_t r, int64_t m) const { return r * pitch() + (m % sw) * phase_len + m / sw; }
  // Where tap (u, v) of output (i, 0) reads: (i·sh + u, v), then +j for output column j.
  int64_t tap_at(int64_t i, int64_t u, int64_t v) const { return padded_at(i * sh + u, v); }
  // The input gradient of a stride-1 plane as a correlation of dy padded by k − 1 − p with the
  // flipped filter: Ho + 2(kh − 1 − ph) − kh + 1 = H (likewise W).
  bool input_grad_is_correlation() const { return sh == 1 && sw == 1 && ph <= kh - 1 && pw <= kw - 1; }
  Plane input_grad_plane() const { return Plane(Ho, Wo, kh, kw, 1, 1, kh - 1 - ph, kw - 1 - pw); }
};

// Calls f(phase_row_offset, k0, k1, m0) for each column phase q of a padded row: entries
// [k0, k1) of the phase (at phase_row_offset) hold the plane's columns m0, m0 + sw, ...
template <class F>
void for_each_phase(const Plane& g, F&& f) {
  for (int64_t q = 0; q < g.sw; ++q) {
    const int64_t k0 = q >= g.pw ? 0 : (g.pw - q + g.sw - 1) / g.sw;  // first k·sw + q >= pw
    const int64_t last = g.pw + g.W - 1 - q;                           // k·sw + q <= pw + W − 1
    const int64_t k1 = last < 0 ? 0 : last / g.sw + 1;
    if (k1 > k0) f(q * g.phase_len, k0, k1, k0 * g.sw + q - g.pw);
  }
}

// dst (g.padded_size()) = the zero-padded, phase-split copy of one plane src (g.in_size()).
template <class T>
void pad_plane(const Plane& g, const T* src, T* dst) {
  std::fill(dst, dst + g.padded_size(), T(0));
  for (int64_t r = 0; r < g.H; ++r) {
    const T* row = src + r * g.W;
    T* out = dst + (r + g.ph) * g.pitch();
    if (g.sw == 1) {
      std::copy(row, row + g.W, out + g.pw);
      continue;
    }
    for_each_phase(g, [&](int64_t off, int64_t k0, int64_t k1, int64_t m0) {
      for (int64_t k = k0; k < k1; ++k) out[off + k] = row[m0 + (k - k0) * g.sw];
    });
  }
}

// The inverse of pad_plane's placement: dst (g.in_size()) = the unpadded part of src.
template <class T>
void unpad_plane(const Plane& g, const T* src, T* dst) {
  for (int64_t r = 0; r < g.H; ++r) {
    T* row = dst + r * g.W;
    const T* in = src + (r + g.ph) * g.pitch();
    if (g.sw == 1) {
      std::copy_n(in + g.pw, g.W, row);
      continue;
    }
    for_each_phase(g, [&](int64_t off, int64_t k0, int64_t k1, int64_t m0) {
      for (int64_t k = k0; k < k1; ++k) row[m0 + (k - k0) * g.sw] = in[off + k];
    });
  }
}

// y (g.out_size()) = b + Σ_t w[t] · tap t of the padded plane xp, summed in tap order for every
// output. KH, KW > 0: a kernel of that size with the taps of a run of columns in registers;
// 0, 0: any size, one pass over the output row per tap (the same sums in the same order).
template <class T, int KH, int KW>
void correlate_plane(const Plane& g, const T* xp, const T* w, T b, T* y) {
  for (int64_t i = 0; i < g.Ho; ++i) {
    T* __restrict yr = y + i * g.Wo;
    if constexpr (KH > 0) {
      const T* s[KH * KW];
      T wt[KH * KW];
      for (int u = 0; u < KH; ++u)
        for (int v = 0; v < KW; ++v) s[u * KW + v] = xp + g.tap_at(i, u, v), wt[u * KW + v] = w[u * KW + v];
#pragma omp simd
      for (int64_t j = 0; j < g.Wo; ++j) {
        T acc = b;
        for (int t = 0; t < KH * KW; ++t) acc += wt[t] * s[t][j];
        yr[j] = acc;
      }
    } else {
      std::fill(yr, yr + g.Wo, b);
      for (int64_t u = 0; u < g.kh; ++u)
        for (int64_t v = 0; v < g.kw; ++v) {
          const T* __restrict s = xp + g.tap_at(i, u, v);
          const T wv = w[u * g.kw + v];
#pragma omp simd
          for (int64_t j = 0; j < g.Wo; ++j) yr[j] += wv * s[j];
        }
    }
  }
}

template <class T>
void correlate(const Plane& g, const T* xp, const T* w, T b, T* y) {
  if (g.kh == 3 && g.kw == 3) return correlate_plane<T, 3, 3>(g, xp, w, b, y);
  correlate_plane<T, 0, 0>(g, xp, w, b, y);
}

// dxp (g.padded_size(), zeroed here) = Σ over outputs and taps of w[t]·dy scattered to where the
// tap read; for strides or paddings where the input gradient is no correlation.
template <class T>
void scatter_plane(const Plane& g, const T* dy, const T* w, T* dxp) {
  std::fill(dxp, dxp + g.padded_size(), T(0));
  for (int64_t i = 0; i < g.Ho; ++i) {
    const T* __restrict d = dy + i * g.Wo;
    for (int64_t u = 0; u < g.kh; ++u)
      for (int64_t v = 0; v < g.kw; ++v) {
        T* __restrict s = dxp + g.tap_at(i, u, v);
        const T wv = w[u * g.kw + v];
#pragma omp simd
        for (int64_t j = 0; j < g.Wo; ++j) s[j] += wv * d[j];
      }
  }
}

// dw[t] = Σ_{i,j} dy[i, j] · tap t of xp and db = Σ dy, for one plane: per column in the
// plane's element type over the rows (acc, (taps + 1)·Wo), then over the columns in double,
// always in the same order.
template <class T>
void filter_grad_plane(const Plane& g, const T* xp, const T* dy, T* acc, double* dw, double* db) {
  const int64_t taps = g.taps(), Wo = g.Wo;
  std::fill(acc, acc + (taps + 1) * Wo, T(0));
  T* __restrict ab = acc + taps * Wo;
  for (int64_t i = 0; i < g.Ho; ++i) {
    const T* __restrict d = dy + i * Wo;
    for (int64_t u = 0; u < g.kh; ++u)
      for (int64_t v = 0; v < g.kw; ++v) {
        const T* __restrict s = xp + g.tap_at(i, u, v);
        T* __restrict a = acc + (u * g.kw + v) * Wo;
#pragma omp simd
        for (int64_t j = 0; j < Wo; ++j) a[j] += d[j] * s[j];
      }
#pragma omp simd
    for (int64_t j = 0; j < Wo; ++j) ab[j] += d[j];
  }
  for (int64_t t = 0; t <= taps; ++t) {
    double sum = 0;
    for (int64_t j = 0; j < Wo; ++j) sum += acc[t * Wo + j];
    (t < taps ? dw[t] : *db) = sum;
  }
}

// The same sums for a KH×KW kernel, a block of kLanes output columns at a time: the taps'
// per-column sums of one block stay in registers over all rows, instead of a pass over memory
// per tap and row. Each column's sum runs over the rows in order as above, and the blocks and
// their columns are added in column order, so the result is a function of the shapes only.
template <class T, int KH, int KW>
void filter_grad_plane_tiled(const Plane& g, const T* xp, const T* dy, double* dw, double* db) {
  constexpr int kTaps = KH * KW, kLanes = 64 / sizeof(T);
  double sums[kTaps + 1] = {};
  for (int64_t j0 = 0; j0 < g.Wo; j0 += kLanes) {
    const int64_t cnt = std::min<int64_t>(kLanes, g.Wo - j0);
    T a[kTaps + 1][kLanes] = {};
    for (int64_t i = 0; i < g.Ho; ++i) {
      const T* d = dy + i * g.Wo + j0;
      const T* s[kTaps];
      for (int u = 0; u < KH; ++u)
        for (int v = 0; v < KW; ++v) s[u * KW + v] = xp + g.tap_at(i, u, v) + j0;
      if (cnt == kLanes) {
        for (int t = 0; t < kTaps; ++t)
#pragma omp simd
          for (int l = 0; l < kLanes; ++l) a[t][l] += d[l] * s[t][l];
#pragma omp simd
        for (int l = 0; l < kLanes; ++l) a[kTaps][l] += d[l];
      } else {
        for (int t = 0; t < kTaps; ++t)
          for (int64_t l = 0; l < cnt; ++l) a[t][l] += d[l] * s[t][l];
        for (int64_t l = 0; l < cnt; ++l) a[kTaps][l] += d[l];
      }
    }
    for (int t = 0; t <= kTaps; ++t)
      for (int64_t l = 0; l < cnt; ++l) sums[t] += a[t][l];
  }
  for (int t = 0; t < kTaps; ++t) dw[t] = sums[t];
  *db = sums[kTaps];
}

template <class T>
void filter_grad(const Plane& g, const T* xp, const T* dy, T* acc, double* dw, double* db) {
  if (g.kh == 3 && g.kw == 3) return filter_grad_plane_tiled<T, 3, 3>(g, xp, dy, dw, db);
  filter_grad_plane(g, xp, dy, acc, dw, db);
}

template <class T>
void depthwise_forward(const Plane& g, int64_t planes, int64_t C, const T* x, const T* w, const T* b, T* y) {
  parallel_for(planes, detail::grain_for(g.taps() * g.out_size() + g.padded_size()), [&](int64_t p0, int64_t p1) {
    std::vector<T> xp(static_cast<size_t>(g.padded_size()));
    for (int64_t p = p0; p < p1; ++p) {
      const int64_t c = p % C;
      pad_plane(g, x + p * g.in_size(), xp.data());
      correlate(g, xp.data(), w + c * g.taps(), b ? b[c] : T(0), y + p * g.out_size());
    }
  });
}

// The gradients asked for (dx, dw, db may be null): one task per run of planes, each plane's
// filter-gradient partials stored by plane and summed over the batch per channel afterwards.
template <class T>
void depthwise_backward(const Plane& g, int64_t N, int64_t C, const T* x, const T* w, const T* dy, T* dx, T* dw,
                        T* db) {
  const int64_t taps = g.taps(), planes = N * C;
  const bool filter = dw || db;
  const bool correlation = g.input_grad_is_correlation();
  const Plane t = correlation ? g.input_grad_plane() : g;
  std::vector<T> flipped;  // flipped[c][taps − 1 − k] = w[c][k]
  if (dx && correlation) {
    flipped.resize(static_cast<size_t>(C * taps));
    for (int64_t c = 0; c < C; ++c)
      for (int64_t k = 0; k < taps; ++k) flipped[c * taps + taps - 1 - k] = w[c * taps + k];
  }
  std::vector<double> part_w(filter ? static_cast<size_t>(planes * taps) : 0);
  std::vector<double> part_b(filter ? static_cast<size_t>(planes) : 0);
  const int64_t work = 2 * taps * g.out_size() + g.padded_size() + t.padded_size();
  parallel_for(planes, detail::grain_for(work), [&](int64_t p0, int64_t p1) {
    std::vector<T> xp(filter ? static_cast<size_t>(g.padded_size()) : 0);
    std::vector<T> acc(filter ? static_cast<size_t>((taps + 1) * g.Wo) : 0);
    std::vector<T> gp(dx ? static_cast<size_t>(t.padded_size()) : 0);  // padded dy, or padded dx
    for (int64_t p = p0; p < p1; ++p) {
      const int64_t c = p % C;
      const T* dyp = dy + p * g.out_size();
      // The input gradient first: its sequential pass over dy leaves the plane in cache for the
      // filter gradient, which reads it in column blocks.
      if (dx && correlation) {
        pad_plane(t, dyp, gp.data());
        correlate(t, gp.data(), flipped.data() + c * taps, T(0), dx + p * g.in_size());
      } else if (dx) {
        scatter_plane(g, dyp, w + c * taps, gp.data());
        unpad_plane(g, gp.data(), dx + p * g.in_size());
      }
      if (filter) {
        pad_plane(g, x + p * g.in_size(), xp.data());
        filter_grad(g, xp.data(), dyp, acc.data(), part_w.data() + p * taps, part_b.data() + p);
      }
    }
  });
  if (!filter) return;
  for (int64_t c = 0; c < C; ++c) {
    for (int64_t k = 0; k < taps && dw; ++k) {
      double sum = 0;
      for (int64_t n = 0; n < N; ++n) sum += part_w[(n * C + c) * taps + k];
      dw[c * taps + k] = static_cast<T>(sum);
    }
    if (db) {
      double sum = 0;
      for (int64_t n = 0; n < N; ++n) sum += part_b[n * C + c];
      db[c] = static_cast<T>(sum);
    }
  }
}

}  // namespace

Tensor depthwise_conv2d(const Tensor& x_in, const Tensor& w_in, const Tensor& b_in, std::array<int64_t, 2> stride,
                        std::array<int64_t, 2> padding) {
  const char* op = "depthwise_conv2d";
  SL_CHECK(x_in.defined() && w_in.defined(), op, ": input and weight must be defined");
  SL_CHECK(x_in.dim() == 4, op, ": input must be 4-d [N, C, H, W], got ", x_in.describe());
  SL_CHECK(w_in.dim() == 4 && w_in.size(1) == 1, op, ": weight must be [C, 1, kh, kw], got ", w_in.describe());
  SL_CHECK(x_in.size(1) == w_in.size(0), op, ": input ", shape_str(x_in.shape()), " has ", x_in.size(1),
           " channels, weight ", shape_str(w_in.shape()), " has ", w_in.size(0), " filters");
  SL_CHECK(x_in.dtype() == w_in.dtype(), op, ": dtypes differ: input ", x_in.describe(), ", weight ",
           w_in.describe());
  if (b_in.defined()) {
    SL_CHECK(b_in.dim() == 1 && b_in.size(0) == w_in.size(0), op, ": bias ", shape_str(b_in.shape()), " must be [",
             w_in.size(0), "] for weight ", shape_str(w_in.shape()));
    SL_CHECK(b_in.dtype() == x_in.dtype(), op, ": dtypes differ: input ", x_in.describe(), ", bias ",
             b_in.describe());
  }
  for (int a = 0; a < 2; ++a)
    SL_CHECK(stride[a] >= 1 && padding[a] >= 0, op, ": stride must be >= 1 and padding >= 0, got stride [",
             stride[0], ", ", stride[1], "], padding [", padding[0], ", ", padding[1], "]");
  const int64_t N = x_in.size(0), C = x_in.size(1), kh = w_in.size(2), kw = w_in.size(3);
  SL_CHECK(kh >= 1 && kw >= 1 && x_in.size(2) + 2 * padding[0] >= kh && x_in.size(3) + 2 * padding[1] >= kw, op,
           ": kernel ", shape_str(w_in.shape()), " does not fit input ", shape_str(x_in.shape()), " with padding [",
           padding[0], ", ", padding[1], "]");
  const Plane g(x_in.size(2), x_in.size(3), kh, kw, stride[0], stride[1], padding[0], padding[1]);

  const Tensor x = x_in.detach().contiguous(), w = w_in.detach().contiguous();
  const Tensor b = b_in.defined() ? b_in.detach().contiguous() : Tensor();
  Tensor y = Tensor::empty({N, C, g.Ho, g.Wo}, x.dtype());
  SL_DISPATCH_FLOAT(x.dtype(), op, [&] {
    using T = scalar_t;
    depthwise_forward<T>(g, N * C, C, x.data<T>(), w.data<T>(), b.defined() ? b.data<T>() : nullptr, y.data<T>());
  });
  if (needs_grad({x_in, w_in, b_in})) {
    const bool gx = x_in.requires_grad(), gw = w_in.requires_grad(), gb = b_in.defined() && b_in.requires_grad();
    record(op, {x_in, w_in, b_in}, {y}, [=](const TensorList& grads) {
      const Tensor dy = grads[0].contiguous();
      TensorList r(3);
      if (gx) r[0] = Tensor::empty(x.shape(), x.dtype());
      if (gw) r[1] = Tensor::empty(w.shape(), w.dtype());
      if (gb) r[2] = Tensor::empty(b.shape(), b.dtype());
      SL_DISPATCH_FLOAT(x.dtype(), op, [&] {
        using T = scalar_t;
        auto ptr = [](Tensor& t) { return t.defined() ? t.data<T>() : nullptr; };
        depthwise_backward<T>(g, N, C, x.data<T>(), w.data<T>(), dy.data<T>(), ptr(r[0]), ptr(r[1]), ptr(r[2]));
      });
      return r;
    });
  }
  return y;
}

}  // namespace sl::nn
