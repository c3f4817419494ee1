// im2col / col2im over spatial tiles (internal to nn/functional/conv.cpp).
//
// Contract: a convolution is described in 3 spatial dims (2-D convolutions use depth 1 and a
// kernel depth of 1). im2col_tile writes, for output positions [p0, p0 + count) of one batch
// item, the column matrix col[r][p - p0] (row r = (c, kz, ky, kx), leading dim `ld`) that
// turns the convolution into the GEMM  out[:, tile] = W[O, C·k] · col. Taps outside the input
// read 0. col2im_tile is its adjoint (same leading dim): it ADDS col back into the
// input-shaped gradient. The *_phased variants do the same on a copy whose rows are split into
// their stride phases (split_phases / merge_phases), so that strided taps move contiguous runs.
#pragma once
#include <algorithm>
#include <array>
#include <cstdint>
#include <type_traits>

#if defined(__AVX512F__)
#include <immintrin.h>
#endif

namespace sl::nn::detail {

struct ConvGeometry {
  int64_t N = 0, C = 0, O = 0;
  std::array<int64_t, 3> in{}, out{}, k{}, stride{}, pad{}, dil{};
  int64_t in_plane() const { return in[0] * in[1] * in[2]; }
  int64_t out_plane() const { return out[0] * out[1] * out[2]; }
  int64_t taps() const { return k[0] * k[1] * k[2]; }
  int64_t rows() const { return C * taps(); }  // the GEMM's inner dimension
};

// The convolution whose forward pass is the input gradient of g (stride 1 only): channels and
// spatial sizes swap and the padding becomes dil·(k − 1) − pad, run with the flipped kernel.
inline ConvGeometry input_grad_geometry(const ConvGeometry& g) {
  ConvGeometry t = g;
  t.C = g.O;
  t.O = g.C;
  t.in = g.out;
  t.out = g.in;
  for (int a = 0; a < 3; ++a) t.pad[a] = g.dil[a] * (g.k[a] - 1) - g.pad[a];
  return t;
}

// Calls seg(row_offset_in_tile, z, y, x0, len) for every run of consecutive output positions in
// one output row (same z, y) of the tile.
template <class Seg>
inline void for_each_row_segment(const ConvGeometry& g, int64_t p0, int64_t count, Seg&& seg) {
  const int64_t W = g.out[2], HW = g.out[1] * g.out[2];
  int64_t z = p0 / HW, y = (p0 % HW) / W, x = p0 % W;
  for (int64_t done = 0; done < count;) {
    const int64_t len = std::min(W - x, count - done);
    seg(done, z, y, x, len);
    done += len;
    x = 0;
    if (++y == g.out[1]) y = 0, ++z;
  }
}

// The range [lo, hi) of i in [0, len) with 0 <= start + i·step < size.
inline void valid_range(int64_t start, int64_t step, int64_t size, int64_t len, int64_t& lo, int64_t& hi) {
  lo = start >= 0 ? 0 : (-start + step - 1) / step;
  hi = start >= size ? 0 : (size - start + step - 1) / step;
  lo = std::min(lo, len);
  hi = std::clamp(hi, lo, len);
}

// Copies a short run (a few dozen elements, an output row segment). For floats with AVX-512 it is
// inlined as masked vector moves: the runs are too short for a memmove call to pay off.
template <class T>
inline void copy_run(const T* src, T* dst, int64_t n) {
#if defined(__AVX512F__)
  if constexpr (std::is_same_v<T, float>) {
    int64_t i = 0;
    for (; i + 16 <= n; i += 16) _mm512_storeu_ps(dst + i, _mm512_loadu_ps(src + i));
    if (i < n) {
      const __mmask16 m = static_cast<__mmask16>((1u << (n - i)) - 1u);
      _mm512_mask_storeu_ps(dst + i, m, _mm512_maskz_loadu_ps(m, src + i));
    }
    return;
  }
#endif
  std::copy(src, src + n, dst);
}

// dst[i] += src[i] for a short run, as copy_run.
template <class T>
inline void add_run(const T* src, T* dst, int64_t n) {
#if defined(__AVX512F__)
  if constexpr (std::is_same_v<T, float>) {
    int64_t i = 0;
    for (; i + 16 <= n; i += 16) _mm512_storeu_ps(dst + i, _mm512_add_ps(_mm512_loadu_ps(dst + i), _mm512_loadu_ps(src + i)));
    if (i < n) {
      const __mmask16 m = static_cast<__mmask16>((1u << (n - i)) - 1u);
      _mm512_mask_storeu_ps(dst + i, m, _mm512_add_ps(_mm512_maskz_loadu_ps(m, dst + i), _mm512_maskz_loadu_ps(m, src + i)));
    }
    return;
  }
#endif
  for (int64_t i = 0; i < n; ++i) dst[i] += src[i];
}

template <class T>
void im2col_tile(const T* x, const ConvGeometry& g, int64_t p0, int64_t count, T* col, int64_t ld) {
  const int64_t D = g.in[0], H = g.in[1], W = g.in[2];
  int64_t r = 0;
  for (int64_t c = 0; c < g.C; ++c)
    for (int64_t kz = 0; kz < g.k[0]; ++kz)
      for (int64_t ky = 0; ky < g.k[1]; ++ky)
        for (int64_t kx = 0; kx < g.k[2]; ++kx, ++r) {
          T* dst = col + r * ld;
          for_each_row_segment(g, p0, count, [&](int64_t off, int64_t z, int64_t y, int64_t x0, int64_t len) {
            T* o = dst + off;
            const int64_t iz = z * g.stride[0] - g.pad[0] + kz * g.dil[0];
            const int64_t iy = y * g.stride[1] - g.pad[1] + ky * g.dil[1];
            if (iz < 0 || iz >= D || iy < 0 || iy >= H) {
              std::fill(o, o + len, T(0));
              return;
            }
            const T* src = x + ((c * D + iz) * H + iy) * W;
            const int64_t ix0 = x0 * g.stride[2] - g.pad[2] + kx * g.dil[2];
            int64_t lo, hi;
            valid_range(ix0, g.stride[2], W, len, lo, hi);
            std::fill(o, o + lo, T(0));
            if (g.stride[2] == 1) {
              copy_run(src + ix0 + lo, o + lo, hi - lo);
            } else {
              const int64_t s = g.stride[2];
              for (int64_t i = lo; i < hi; ++i) o[i] = src[ix0 + i * s];
            }
            std::fill(o + hi, o + len, T(0));
          });
        }
}

// A copy of x whose rows are split into their `stride[2]` phases: phased row (c, z, y) holds
// phase p = ix mod s as elements x[.., s·j + p] for j < phase_len = ceil(W / s). Strided im2col
// then copies contiguous runs instead of gathering every s-th element (half of the forward time
// of a 7×7 stride-2 stem went into that gather).
struct PhasedRows {
  int64_t stride = 1, phase_len = 0;
  int64_t row_pitch() const { return stride * phase_len; }
};

inline PhasedRows phased_rows(const ConvGeometry& g) {
  return {g.stride[2], (g.in[2] + g.stride[2] - 1) / g.stride[2]};
}

// rows: number of input rows (N·C·D·H); out holds rows × row_pitch().
template <class T>
void split_phases(const T* x, int64_t rows, int64_t W, const PhasedRows& ph, T* out) {
  for (int64_t r = 0; r < rows; ++r) {
    const T* src = x + r * W;
    T* dst = out + r * ph.row_pitch();
    for (int64_t p = 0; p < ph.stride; ++p)
      for (int64_t j = 0; j < ph.phase_len; ++j) {
        const int64_t ix = ph.stride * j + p;
        dst[p * ph.phase_len + j] = ix < W ? src[ix] : T(0);
      }
  }
}

// im2col_tile on a phased copy (xp: one batch item, C·D·H phased rows): identical output.
template <class T>
void im2col_tile_phased(const T* xp, const ConvGeometry& g, const PhasedRows& ph, int64_t p0, int64_t count, T* col,
                        int64_t ld) {
  const int64_t D = g.in[0], H = g.in[1], W = g.in[2], s = ph.stride;
  int64_t r = 0;
  for (int64_t c = 0; c < g.C; ++c)
    for (int64_t kz = 0; kz < g.k[0]; ++kz)
      for (int64_t ky = 0; ky < g.k[1]; ++ky)
        for (int64_t kx = 0; kx < g.k[2]; ++kx, ++r) {
          T* dst = col + r * ld;
          for_each_row_segment(g, p0, count, [&](int64_t off, int64_t z, int64_t y, int64_t x0, int64_t len) {
            T* o = dst + off;
            const int64_t iz = z * g.stride[0] - g.pad[0] + kz * g.dil[0];
            const int64_t iy = y * g.stride[1] - g.pad[1] + ky * g.dil[1];
            if (iz < 0 || iz >= D || iy < 0 || iy >= H) {
              std::fill(o, o + len, T(0));
              return;
            }
            const int64_t ix0 = x0 * s - g.pad[2] + kx * g.dil[2];
            int64_t lo, hi;
            valid_range(ix0, s, W, len, lo, hi);
            const int64_t phase = ((ix0 % s) + s) % s, j0 = (ix0 - phase) / s;  // ix0 + s·i = s·(j0 + i) + phase
            const T* src = xp + ((c * D + iz) * H + iy) * ph.row_pitch() + phase * ph.phase_len + j0;
            std::fill(o, o + lo, T(0));
            copy_run(src + lo, o + lo, hi - lo);
            std::fill(o + hi, o + len, T(0));
          });
        }
}

// split_phases' inverse: x[r][ix] = phased[r][(ix mod s)·phase_len + ix / s] for rows r < rows.
template <class T>
void merge_phases(const T* phased, int64_t rows, int64_t W, const PhasedRows& ph, T* x) {
  for (int64_t r = 0; r < rows; ++r) {
    const T* src = phased + r * ph.row_pitch();
    T* dst = x + r * W;
    for (int64_t p = 0; p < ph.stride; ++p)
      for (int64_t j = 0; j < ph.phase_len && ph.stride * j + p < W; ++j) dst[ph.stride * j + p] = src[p * ph.phase_len + j];
  }
}

// The scatter walk shared by the col2im variants: for every column row r (channel c, tap kz, ky,
// kx, in that order) and every output-row segment of the tile, the input row (c, iz, iy) it lands
// in, its first input column ix0 (stepping by stride[2]) and the valid part [lo, hi) of the run,
// whose values are col[r·ld + off + lo ..]. Rows falling outside the input are skipped.
template <class F>
void for_each_col2im_run(const ConvGeometry& g, int64_t p0, int64_t count, F&& f) {
  const int64_t D = g.in[0], H = g.in[1], W = g.in[2];
  int64_t r = 0;
  for (int64_t c = 0; c < g.C; ++c)
    for (int64_t kz = 0; kz < g.k[0]; ++kz)
      for (int64_t ky = 0; ky < g.k[1]; ++ky)
        for (int64_t kx = 0; kx < g.k[2]; ++kx, ++r)
          for_each_row_segment(g, p0, count, [&](int64_t off, int64_t z, int64_t y, int64_t x0, int64_t len) {
            const int64_t iz = z * g.stride[0] - g.pad[0] + kz * g.dil[0];
            const int64_t iy = y * g.stride[1] - g.pad[1] + ky * g.dil[1];
            if (iz < 0 || iz >= D || iy < 0 || iy >= H) return;
            const int64_t ix0 = x0 * g.stride[2] - g.pad[2] + kx * g.dil[2];
            int64_t lo, hi;
            valid_range(ix0, g.stride[2], W, len, lo, hi);
            f(r, c, iz, iy, ix0, off, lo, hi);
          });
}

// col2im_tile into a phased gradient (dxp: one batch item, C·D·H phased rows, see
// split_phases): each tap of an output-row segment adds one contiguous run instead of every s-th
// element. Every element receives the same additions in the same order as with col2im_tile.
template <class T>
void col2im_tile_phased(const T* col, const ConvGeometry& g, const PhasedRows& ph, int64_t p0, int64_t count, T* dxp,
                        int64_t ld) {
  const int64_t D = g.in[0], H = g.in[1], s = ph.stride;
  for_each_col2im_run(g, p0, count,
                      [&](int64_t r, int64_t c, int64_t iz, int64_t iy, int64_t ix0, int64_t off, int64_t lo, int64_t hi) {
                        const int64_t phase = ((ix0 % s) + s) % s, j0 = (ix0 - phase) / s;
                        T* dst = dxp + ((c * D + iz) * H + iy) * ph.row_pitch() + phase * ph.phase_len + j0;
                        add_run(col + r * ld + off + lo, dst + lo, hi - lo);
                      });
}

template <class T>
void col2im_tile(const T* col, const ConvGeometry& g, int64_t p0, int64_t count, T* dx, int64_t ld) {
  const int64_t D = g.in[0], H = g.in[1], W = g.in[2], s = g.stride[2];
  for_each_col2im_run(g, p0, count,
                      [&](int64_t r, int64_t c, int64_t iz, int64_t iy, int64_t ix0, int64_t off, int64_t lo, int64_t hi) {
                        T* o = dx + ((c * D + iz) * H + iy) * W;
                        const T* src = col + r * ld + off;
                        for (int64_t i = lo; i < hi; ++i) o[ix0 + i * s] += src[i];
                      });
}

}  // namespace sl::nn::detail
