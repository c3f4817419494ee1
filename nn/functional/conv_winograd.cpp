#include "nn/functional/conv_winograd.h"

#include <algorithm>
#include <vector>

#if defined(__AVX512F__)
#include <immintrin.h>
#endif

#include "autodiff/transpose16.h"
#include "nn/functional/work_grain.h"
#include "util/parallel.h"

namespace sl::nn::detail {

// Written straight in pack_rows' layout (row blocks [O / 8][R][8]), one block of 8 output
// channels per task: a separate transform pass and four packings took 11 ms for ResNet-18's
// 512-channel layer, four times its GEMM.
WinogradWeights winograd_weights(const ConvGeometry& g, int axis, const float* w, bool flipped) {
  const std::array<int64_t, 3> ws = {g.k[1] * g.k[2], g.k[2], 1};  // tap strides of each axis in w
  const int64_t R = g.rows() / 3, taps = g.taps(), blocks = (g.O + kBlockRows - 1) / kBlockRows;
  WinogradWeights v;
  v.stride = blocks * R * kBlockRows;
  v.storage = cached_floats(4 * v.stride);
  // Tap m of row r of output channel o is w[o·o_stride + row_at[r] + m·step]. Flipped, w holds
  // [C][O][taps] and tap k of (o, c) is w[c][o][taps − 1 − k].
  std::vector<int64_t> row_at;
  row_at.reserve(static_cast<size_t>(R));
  for (int64_t c = 0; c < g.C; ++c)
    for (int64_t k0 = 0; k0 < (axis == 0 ? 1 : g.k[0]); ++k0)
      for (int64_t k1 = 0; k1 < (axis == 1 ? 1 : g.k[1]); ++k1)
        for (int64_t k2 = 0; k2 < (axis == 2 ? 1 : g.k[2]); ++k2) {
          const int64_t k = k0 * ws[0] + k1 * ws[1] + k2 * ws[2];
          row_at.push_back(flipped ? c * g.O * taps + taps - 1 - k : c * taps + k);
        }
  const int64_t step = flipped ? -ws[axis] : ws[axis], o_stride = flipped ? taps : g.C * taps;
  parallel_for(blocks, grain_for(R * kBlockRows * 3), [&](int64_t b0, int64_t b1) {
    for (int64_t blk = b0; blk < b1; ++blk) {
      const int64_t rows = std::min(kBlockRows, g.O - blk * kBlockRows);
      const float* wo[kBlockRows];
      for (int64_t i = 0; i < kBlockRows; ++i) wo[i] = w + (blk * kBlockRows + std::min(i, rows - 1)) * o_stride;
      float* d0 = v.storage.get() + 0 * v.stride + blk * R * kBlockRows;
      float* d1 = v.storage.get() + 1 * v.stride + blk * R * kBlockRows;
      float* d2 = v.storage.get() + 2 * v.stride + blk * R * kBlockRows;
      float* d3 = v.storage.get() + 3 * v.stride + blk * R * kBlockRows;
      int64_t r0 = 0;  // rows below r0 are done
#if defined(__AVX512F__)
      static_assert(kBlockRows == 8);
      // Unflipped along the innermost axis, row r's taps are w[o][3r .. 3r + 2] (row_at[r] = 3r):
      // 32 rows of the block's 8 output channels per step, deinterleaved from 96 contiguous floats
      // per channel, then put in pack_rows' [r][8] layout by the register transpose that
      // pack_rows uses. The same arithmetic as the loop below, so the same bits; the scalar loop
      // (3 gathers and 4 scattered stores per value) was 22% of ResNet-18's 512-channel layer's
      // forward+backward (perf, 1 thread).
      if (!flipped && axis == 2 && step == 1 && g.k[2] == 3)
        for (; r0 + 32 <= R; r0 += 32) {
          const __m512i i0 = _mm512_setr_epi32(0, 3, 6, 9, 12, 15, 18, 21, 24, 27, 30, 0, 0, 0, 0, 0);
          const __m512i i1 = _mm512_setr_epi32(1, 4, 7, 10, 13, 16, 19, 22, 25, 28, 31, 0, 0, 0, 0, 0);
          const __m512i i2 = _mm512_setr_epi32(2, 5, 8, 11, 14, 17, 20, 23, 26, 29, 0, 0, 0, 0, 0, 0);
          // g_m[h][i]: tap m of rows r0 + 16h .. r0 + 16h + 15 of channel row i.
          __m512 c0[16], c1[16], c2[16], c3[16];
          for (int64_t h = 0; h < 2; ++h)
            for (int64_t i = 0; i < kBlockRows; ++i) {
              __m512 g0 = _mm512_setzero_ps(), g1 = g0, g2 = g0;
              if (i < rows) {
                const float* src = wo[i] + 3 * (r0 + 16 * h);
                const __m512 a = _mm512_loadu_ps(src), b = _mm512_loadu_ps(src + 16), c = _mm512_loadu_ps(src + 32);
                // Taps m of 16 rows: elements m, m + 3, ..., m + 45 of a | b | c.
                const __m512 ab0 = _mm512_permutex2var_ps(a, i0, b), ab1 = _mm512_permutex2var_ps(a, i1, b);
                const __m512 ab2 = _mm512_permutex2var_ps(a, i2, b);
                // Lanes 11-15 (10-15 for tap 2) come from c: elements 33 + 3k + m - 32 of c.
                const __m512i j0 = _mm512_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 17, 20, 23, 26, 29);
                const __m512i j1 = _mm512_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 18, 21, 24, 27, 30);
                const __m512i j2 = _mm512_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 16, 19, 22, 25, 28, 31);
                g0 = _mm512_permutex2var_ps(ab0, j0, c);
                g1 = _mm512_permutex2var_ps(ab1, j1, c);
                g2 = _mm512_permutex2var_ps(ab2, j2, c);
              }
              c0[8 * h + i] = g0;
              c1[8 * h + i] = _mm512_mul_ps(_mm512_add_ps(_mm512_add_ps(g0, g1), g2), _mm512_set1_ps(0.5f));
              c2[8 * h + i] = _mm512_mul_ps(_mm512_add_ps(_mm512_sub_ps(g0, g1), g2), _mm512_set1_ps(0.5f));
              c3[8 * h + i] = g2;
            }
          float* const dst[4] = {d0, d1, d2, d3};
          __m512* const comp[4] = {c0, c1, c2, c3};
          for (int k = 0; k < 4; ++k) {
            transpose16(comp[k]);  // comp[k][j] = {channels 0-7 at row r0 + j, channels 0-7 at r0 + 16 + j}
            for (int64_t j = 0; j < 16; ++j) {
              _mm256_storeu_ps(dst[k] + (r0 + j) * kBlockRows, _mm512_castps512_ps256(comp[k][j]));
              _mm256_storeu_ps(dst[k] + (r0 + 16 + j) * kBlockRows,
                               _mm256_castpd_ps(_mm512_extractf64x4_pd(_mm512_castps_pd(comp[k][j]), 1)));
            }
          }
        }
#endif
      for (int64_t r = r0; r < R; ++r) {
        const int64_t at = row_at[r];
        for (int64_t i = 0; i < kBlockRows; ++i) {
          const float* t = wo[i] + at;
          const bool real = i < rows;  // rows past O: zeros, as pack_rows pads them
          const float g0 = real ? t[0] : 0.0f, g1 = real ? t[step] : 0.0f, g2 = real ? t[2 * step] : 0.0f;
          d0[r * kBlockRows + i] = g0;
          d1[r * kBlockRows + i] = (g0 + g1 + g2) * 0.5f;
          d2[r * kBlockRows + i] = (g0 - g1 + g2) * 0.5f;
          d3[r * kBlockRows + i] = g2;
        }
      }
    }
  });
  return v;
}

namespace {

// Columns: q = (n·Ho + oy)·Wo2 + j, the pair (2j, 2j + 1) of output row oy of item n.
// Panels are 48 columns wide, or 32 where that wastes at most 15% and 48 does not (ResNet-18's
// 4 × 8 stage at batch 4: 64 pairs, two 32-column panels instead of 96 columns for 64).
struct RowPairs {
  int64_t Wo2 = 0, Q = 0, width = kPanelCols, panels = 0, K = 0;
  static bool tight(int64_t q, int64_t w) { return ((q + w - 1) / w * w - q) * 100 <= 15 * ((q + w - 1) / w * w); }
  explicit RowPairs(const ConvGeometry& g) : Wo2((g.out[2] + 1) / 2), Q(g.N * g.out[1] * Wo2), K(g.C * g.k[1]) {
    if (!tight(Q, kPanelCols) && tight(Q, 32)) width = 32;
    panels = (Q + width - 1) / width;
  }
  bool fits() const { return tight(Q, width); }
  // Components are kSkew floats more than their panels apart: at a whole number of 4 KiB pages
  // (K·48 floats often is) the four stores of each pair alias in the store buffer, which made
  // gathering cost as much as the GEMM. The skew also holds the narrow kernel's overrun.
  static constexpr int64_t kSkew = 80;
  int64_t comp() const { return panels * K * width + kSkew; }
  int64_t floats() const { return 4 * comp(); }
};

}  // namespace

void winograd_pairs(const float* d, int64_t pairs, float* u, int64_t comp) {
  float *u1 = u, *u2 = u + comp, *u3 = u + 2 * comp, *u4 = u + 3 * comp;
  int64_t j0 = 0;
#if defined(__AVX512F__)
  // 16 pairs per step: the even and odd lanes of d[2j .. 2j + 31] and of the same shifted by one pair.
  const __m512i even = _mm512_setr_epi32(0, 2, 4, 6, 8, 10, 12, 14, 16, 18, 20, 22, 24, 26, 28, 30);
  const __m512i odd = _mm512_add_epi32(even, _mm512_set1_epi32(1));
  for (; j0 < pairs; j0 += 16) {
    const __mmask16 m = static_cast<__mmask16>(pairs - j0 >= 16 ? 0xffffu : (1u << (pairs - j0)) - 1u);
    const float* s0 = d + 2 * j0;
    const __m512 a = _mm512_loadu_ps(s0), b = _mm512_loadu_ps(s0 + 16);
    const __m512 a2 = _mm512_loadu_ps(s0 + 2), b2 = _mm512_loadu_ps(s0 + 18);
    const __m512 d0 = _mm512_permutex2var_ps(a, even, b), d1 = _mm512_permutex2var_ps(a, odd, b);
    const __m512 d2 = _mm512_permutex2var_ps(a2, even, b2), d3 = _mm512_permutex2var_ps(a2, odd, b2);
    _mm512_mask_storeu_ps(u1 + j0, m, _mm512_sub_ps(d0, d2));
    _mm512_mask_storeu_ps(u2 + j0, m, _mm512_add_ps(d1, d2));
    _mm512_mask_storeu_ps(u3 + j0, m, _mm512_sub_ps(d2, d1));
    _mm512_mask_storeu_ps(u4 + j0, m, _mm512_sub_ps(d1, d3));
  }
#endif
  for (int64_t j = j0; j < pairs; ++j) {
    const float d0 = d[2 * j], d1 = d[2 * j + 1], d2 = d[2 * j + 2], d3 = d[2 * j + 3];
    u1[j] = d0 - d2;
    u2[j] = d1 + d2;
    u3[j] = d2 - d1;
    u4[j] = d1 - d3;
  }
}

bool winograd_rows_supported(const ConvGeometry& g) {
  if (!gemm_kernel_available() || g.in[0] != 1 || g.k[0] != 1 || g.k[2] != 3 || g.dil[2] != 1) return false;
  for (int a = 0; a < 3; ++a)
    if (g.stride[a] != 1) return false;
  const RowPairs rp(g);
  return rp.floats() <= (int64_t{64} << 20) / 4 && rp.fits();
}

void winograd_rows_forward(const ConvGeometry& g, const float* x, const float* w, const float* b, float* y,
                           bool flipped) {
  const RowPairs rp(g);
  const int64_t H = g.in[1], W = g.in[2], Ho = g.out[1], Wo = g.out[2], KY = g.k[1], K = rp.K;
  const int64_t width = rp.width, panel_floats = K * width, comp = rp.comp();
  const WinogradWeights v = winograd_weights(g, 2, w, flipped);
  // cols[i][p][k][48]: component i of panel p, k = (c, ky). Each (n, c) task fills its own rows
  // k of its own columns; the columns past Q (the last panel's tail) are zeros.
  const CachedFloats cols = cached_floats(rp.floats());
  for (int64_t i = 0; i < 4; ++i)
    for (int64_t k = 0; k < K; ++k) {
      float* row = cols.get() + i * comp + (rp.panels - 1) * panel_floats + k * width;
      std::fill(row + rp.Q - (rp.panels - 1) * width, row + width, 0.0f);
    }
  // Per (n, c) plane: the zero-padded plane (Hp rows of Wp floats, plus a vector's slack), its
  // four transforms row by row (Hp rows of Wo2 pairs), then each (oy, ky) row copied into the panels.
  const int64_t Hp = H + 2 * g.pad[1], Wp = 2 * rp.Wo2 + 2;
  parallel_for(g.N * g.C, grain_for(Ho * KY * W * 4), [&](int64_t t0, int64_t t1) {
    std::vector<float> plane(static_cast<size_t>(Hp * Wp + 32), 0.0f), u(static_cast<size_t>(4 * Hp * rp.Wo2));
    for (int64_t t = t0; t < t1; ++t) {
      const int64_t n = t / g.C, c = t % g.C;
      const float* xc = x + t * H * W;
      const int64_t lo = std::min(g.pad[2], Wp), hi = std::clamp(g.pad[2] + W, lo, Wp);
      for (int64_t yy = 0; yy < H; ++yy)  // the borders stay zero from the first plane
        std::copy(xc + yy * W + (lo - g.pad[2]), xc + yy * W + (hi - g.pad[2]), plane.data() + (yy + g.pad[1]) * Wp + lo);
      for (int64_t yp = 0; yp < Hp; ++yp)
        winograd_pairs(plane.data() + yp * Wp, rp.Wo2, u.data() + yp * rp.Wo2, Hp * rp.Wo2);
      for (int64_t oy = 0; oy < Ho; ++oy)
        for (int64_t ky = 0; ky < KY; ++ky) {
          const float* src = u.data() + (oy + ky * g.dil[1]) * rp.Wo2;
          const int64_t k = c * KY + ky, q0 = (n * Ho + oy) * rp.Wo2;
          for (int64_t j0 = 0; j0 < rp.Wo2;) {  // runs of the row within one panel
            const int64_t q = q0 + j0, len = std::min(rp.Wo2 - j0, width - q % width);
            float* dst = cols.get() + (q / width) * panel_floats + k * width + q % width;
            for (int64_t i = 0; i < 4; ++i) copy_run(src + i * Hp * rp.Wo2 + j0, dst + i * comp, len);
            j0 += len;
          }
        }
    }
  });
  // Tasks (block of output rows, panel): few panels, so the rows are split as well (>= 16 tasks).
  const int64_t row_blocks = (g.O + kBlockRows - 1) / kBlockRows;
  const int64_t parts = std::min(row_blocks, (16 + rp.panels - 1) / rp.panels);
  parallel_for(parts * rp.panels, grain_for(4 * g.O * K * width / parts), [&](int64_t t0, int64_t t1) {
    std::vector<float> m(static_cast<size_t>(4 * g.O * width));
    for (int64_t t = t0; t < t1; ++t) {
      const int64_t part = t / rp.panels, p = t % rp.panels;
      const int64_t o0 = part * row_blocks / parts * kBlockRows;
      const int64_t o1 = std::min(g.O, (part + 1) * row_blocks / parts * kBlockRows);
      const int64_t n_cols = std::min(width, rp.Q - p * width), tile = (o1 - o0) * width;
      for (int64_t i = 0; i < 4; ++i)
        (width == kPanelCols ? gemm_panel : gemm_panel_narrow)(
            v.data(i) + o0 * K, o1 - o0, K, cols.get() + i * comp + p * panel_floats, n_cols, nullptr,
            m.data() + i * tile, width, width);
      for (int64_t col = 0; col < n_cols; ++col) {
        const int64_t q = p * width + col, j = q % rp.Wo2, row = q / rp.Wo2;  // row = n·Ho + oy
        const int64_t n = row / Ho, oy = row % Ho;
        for (int64_t o = o0; o < o1; ++o) {
          const float* m1 = m.data() + (o - o0) * width + col;
          const float m2 = m1[tile], m3 = m1[2 * tile], m4 = m1[3 * tile];
          const float bias = b ? b[o] : 0.0f;
          float* yo = y + ((n * g.O + o) * Ho + oy) * Wo + 2 * j;
          yo[0] = m1[0] + m2 + m3 + bias;
          if (2 * j + 1 < Wo) yo[1] = m2 - m3 - m4 + bias;
        }
      }
    }
  });
}

}  // namespace sl::nn::detail
