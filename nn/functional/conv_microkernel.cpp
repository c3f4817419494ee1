#include "nn/functional/conv_microkernel.h"

#include <algorithm>

#if defined(__AVX512F__) || (defined(__AVX2__) && defined(__FMA__))
#include <immintrin.h>
#endif

#include "autodiff/gemm_tile.h"
#include "nn/functional/transpose8.h"
#include "nn/functional/work_grain.h"
#include "util/parallel.h"

namespace sl::nn::detail {

PackedRows pack_weights_flipped(const float* w, int64_t O, int64_t C, int64_t taps) {
  const int64_t blocks = (C + kBlockRows - 1) / kBlockRows, K = O * taps;
  PackedRows packed{cached_floats(blocks * K * kBlockRows)};
  parallel_for(blocks, grain_for(K * kBlockRows), [&](int64_t b0, int64_t b1) {
    for (int64_t blk = b0; blk < b1; ++blk) {
      const int64_t c0 = blk * kBlockRows, rows = std::min(kBlockRows, C - c0);
      float* dst = packed.buffer.get() + blk * K * kBlockRows;
      for (int64_t o = 0; o < O; ++o) {  // the block's kernels of output channel o: rows × taps contiguous floats
        const float* src = w + (o * C + c0) * taps;
        float* d = dst + o * taps * kBlockRows;
        int64_t t0 = 0;  // source taps below t0 are done
#if defined(__AVX2__)
        static_assert(kBlockRows == 8);
        // A full block is an 8 × taps matrix: 8 source taps at a time, one 8 × 8 transpose; source
        // tap t0 + j lands at packed position taps − 1 − t0 − j. Moves the same bits as the loop below.
        if (rows == kBlockRows)
          for (; t0 + 8 <= taps; t0 += 8) {
            __m256 r[8];
            for (int i = 0; i < 8; ++i) r[i] = _mm256_loadu_ps(src + i * taps + t0);
            transpose8(r);
            for (int j = 0; j < 8; ++j) _mm256_storeu_ps(d + (taps - 1 - t0 - j) * kBlockRows, r[j]);
          }
#endif
        for (int64_t s = t0; s < taps; ++s)
          for (int64_t i = 0; i < kBlockRows; ++i) d[(taps - 1 - s) * kBlockRows + i] = i < rows ? src[i * taps + s] : 0.0f;
      }
    }
  });
  return packed;
}

#if defined(__AVX512F__)

using sl::detail::gemm_tile::micro_kernel;

// {Σ lanes of v0, ..., Σ lanes of v7}: a shuffle tree (24 operations) instead of eight
// independent horizontal reductions (about 64).
inline __m256 reduce8(__m512 v0, __m512 v1, __m512 v2, __m512 v3, __m512 v4, __m512 v5, __m512 v6, __m512 v7) {
  auto pair = [](__m512 a, __m512 b) { return _mm512_add_ps(_mm512_unpacklo_ps(a, b), _mm512_unpackhi_ps(a, b)); };
  auto quad = [](__m512 ab, __m512 cd) {  // per 128-bit lane: {a, b, c, d} partial sums
    return _mm512_add_ps(_mm512_shuffle_ps(ab, cd, _MM_SHUFFLE(1, 0, 1, 0)),
                         _mm512_shuffle_ps(ab, cd, _MM_SHUFFLE(3, 2, 3, 2)));
  };
  const __m512 lo = quad(pair(v0, v1), pair(v2, v3)), hi = quad(pair(v4, v5), pair(v6, v7));
  const __m512 u = _mm512_add_ps(_mm512_shuffle_f32x4(lo, hi, _MM_SHUFFLE(2, 0, 2, 0)),
                                 _mm512_shuffle_f32x4(lo, hi, _MM_SHUFFLE(3, 1, 3, 1)));
  const __m512 t = _mm512_add_ps(_mm512_shuffle_f32x4(u, u, _MM_SHUFFLE(2, 0, 2, 0)),
                                 _mm512_shuffle_f32x4(u, u, _MM_SHUFFLE(3, 1, 3, 1)));
  return _mm512_castps512_ps256(t);
}

// dw[o][k] += Σ_i dy[o][i] · base[row_offset[k] + i]: 8 rows of dy against 3 windows of the padded
// input, 16 positions per step, 24 vector accumulators reduced once at the end of the range.
// kItems: whether several items share the accumulators (a separate instance, so that the
// single-item loop compiles exactly as it did without the item loop).
template <bool kItems>
void weight_grad_kernel(const float* dy, int64_t ldy, int64_t M, const float* base, const int64_t* row_offset,
                        int64_t K, int64_t len, float* dw, int64_t items, int64_t dy_item, int64_t base_item) {
  const int64_t full = len / 16 * 16;
  const __mmask16 tail = static_cast<__mmask16>((1u << (len - full)) - 1u);
  for (int64_t o0 = 0; o0 < M; o0 += kBlockRows) {
    const int64_t rows = std::min(kBlockRows, M - o0);
    const float* d0[kBlockRows];
    for (int64_t i = 0; i < kBlockRows; ++i) d0[i] = dy + (o0 + std::min(i, rows - 1)) * ldy;  // extra rows dropped
    for (int64_t k0 = 0; k0 < K; k0 += 3) {
      const int64_t cols = std::min<int64_t>(3, K - k0);
#define SL_ROW(i) __m512 a##i##0 = _mm512_setzero_ps(), a##i##1 = a##i##0, a##i##2 = a##i##0;
      SL_ROW(0) SL_ROW(1) SL_ROW(2) SL_ROW(3) SL_ROW(4) SL_ROW(5) SL_ROW(6) SL_ROW(7)
#undef SL_ROW
#define SL_FMA(r, m)                                     \
  {                                                      \
    const __m512 g = _mm512_maskz_loadu_ps(m, d[r] + i); \
    a##r##0 = _mm512_fmadd_ps(g, v0, a##r##0);           \
    a##r##1 = _mm512_fmadd_ps(g, v1, a##r##1);           \
    a##r##2 = _mm512_fmadd_ps(g, v2, a##r##2);           \
  }
#define SL_STEP(m)                                                                                 \
  {                                                                                                \
    const __m512 v0 = _mm512_maskz_loadu_ps(m, x0 + i);                                            \
    const __m512 v1 = _mm512_maskz_loadu_ps(m, x1 + i);                                            \
    const __m512 v2 = _mm512_maskz_loadu_ps(m, x2 + i);                                            \
    SL_FMA(0, m) SL_FMA(1, m) SL_FMA(2, m) SL_FMA(3, m) SL_FMA(4, m) SL_FMA(5, m) SL_FMA(6, m) SL_FMA(7, m) \
  }
      // An opaque all-ones mask: with a constant one GCC folds each dy load into its three FMAs
      // as memory operands (27 loads per step instead of 11), and the loop becomes load-bound.
      unsigned all_lanes = 0xffffu;
      asm("" : "+r"(all_lanes));
      const __mmask16 all = static_cast<__mmask16>(all_lanes);
      for (int64_t t = 0; t < (kItems ? items : 1); ++t) {
        const float* d[kBlockRows];
        for (int64_t r = 0; r < kBlockRows; ++r) d[r] = d0[r] + t * dy_item;
        const float* x0 = base + t * base_item + row_offset[k0];
        const float* x1 = base + t * base_item + row_offset[k0 + std::min<int64_t>(1, cols - 1)];
        const float* x2 = base + t * base_item + row_offset[k0 + std::min<int64_t>(2, cols - 1)];
        int64_t i = 0;
        for (; i < full; i += 16) SL_STEP(all)
        if (tail) SL_STEP(tail)
      }
#undef SL_STEP
#undef SL_FMA
      alignas(32) float sums[3][8];
      _mm256_store_ps(sums[0], reduce8(a00, a10, a20, a30, a40, a50, a60, a70));
      _mm256_store_ps(sums[1], reduce8(a01, a11, a21, a31, a41, a51, a61, a71));
      _mm256_store_ps(sums[2], reduce8(a02, a12, a22, a32, a42, a52, a62, a72));
      for (int64_t r = 0; r < rows; ++r)
        for (int64_t j = 0; j < cols; ++j) dw[(o0 + r) * K + k0 + j] += sums[j][r];
    }
  }
}

void conv_weight_grad_window(const float* dy, int64_t ldy, int64_t M, const float* base, const int64_t* row_offset,
                             int64_t K, int64_t len, float* dw, int64_t items, int64_t dy_item, int64_t base_item) {
  if (items > 1) return weight_grad_kernel<true>(dy, ldy, M, base, row_offset, K, len, dw, items, dy_item, base_item);
  weight_grad_kernel<false>(dy, ldy, M, base, row_offset, K, len, dw, 1, 0, 0);
}

namespace {

// One call of conv_weight_grad_outer for V vectors of 16 output channels and up to T taps:
// acc[t][j] = Σ_items Σ_i x_t[i] · dyT[i][16j ..], x_t = the window of tap t. Taps past `taps`
// repeat the last one (loads stay inside its window) and are not stored.
template <int V, int T>
inline void weight_grad_outer_block(const float* dyT, int64_t ldp, const float* base, const int64_t* row_offset,
                                    int64_t taps, int64_t len, float* dwT, int64_t ld_dwT, int64_t items,
                                    int64_t dy_item, int64_t base_item) {
  __m512 acc[T][V];
  for (int t = 0; t < T; ++t)
    for (int j = 0; j < V; ++j) acc[t][j] = _mm512_setzero_ps();
  for (int64_t it = 0; it < items; ++it) {
    const float* x[T];
    for (int t = 0; t < T; ++t) x[t] = base + it * base_item + row_offset[std::min<int64_t>(t, taps - 1)];
    const float* d = dyT + it * dy_item;
    for (int64_t i = 0; i < len; ++i, d += ldp) {
      __m512 dv[V];
      for (int j = 0; j < V; ++j) dv[j] = _mm512_loadu_ps(d + 16 * j);
#pragma GCC unroll 12
      for (int t = 0; t < T; ++t) {
        const __m512 b = _mm512_set1_ps(x[t][i]);
#pragma GCC unroll 4
        for (int j = 0; j < V; ++j) acc[t][j] = _mm512_fmadd_ps(b, dv[j], acc[t][j]);
      }
    }
  }
  for (int t = 0; t < T; ++t) {
    if (t >= taps) break;
    for (int j = 0; j < V; ++j) {
      float* dst = dwT + t * ld_dwT + 16 * j;
      _mm512_storeu_ps(dst, _mm512_add_ps(_mm512_loadu_ps(dst), acc[t][j]));
    }
  }
}

template <int V, int T>
void weight_grad_outer_taps(const float* dyT, int64_t ldp, const float* base, const int64_t* row_offset, int64_t K,
                            int64_t len, float* dwT, int64_t ld_dwT, int64_t items, int64_t dy_item,
                            int64_t base_item) {
  for (int64_t k0 = 0; k0 < K; k0 += T)
    weight_grad_outer_block<V, T>(dyT, ldp, base, row_offset + k0, std::min<int64_t>(T, K - k0), len,
                                  dwT + k0 * ld_dwT, ld_dwT, items, dy_item, base_item);
}

}  // namespace

namespace {

// One block of up to 8 triples of conv_weight_grad_shift: acc[b][k] = Σ_j x_b[j] · dyT[j − k]
// (dyT zero outside [0, len)), i.e. tap k of triple b summed in position order; one broadcast
// of x_b[j] feeds the three taps. Triples past `count` repeat the last one and are not stored.
template <int T>
inline void weight_grad_shift_block(const float* dyT, int64_t ldp, const float* base, const int64_t* offset,
                                    const int64_t* tap, int64_t tap_step, int64_t count, int64_t len, float* dwT,
                                    int64_t ld_dwT, int64_t items, int64_t dy_item, int64_t base_item) {
  __m512 acc[T][3];
  for (int b = 0; b < T; ++b) acc[b][0] = acc[b][1] = acc[b][2] = _mm512_setzero_ps();
  for (int64_t it = 0; it < items; ++it) {
    const float* x[T];
    for (int b = 0; b < T; ++b) x[b] = base + it * base_item + offset[std::min<int64_t>(b, count - 1)];
    const float* d = dyT + it * dy_item;
    __m512 d1 = _mm512_setzero_ps(), d2 = d1;  // dy at j − 1 and j − 2
    auto step = [&](int64_t j, __m512 d0) {
#pragma GCC unroll 8
      for (int b = 0; b < T; ++b) {
        const __m512 v = _mm512_set1_ps(x[b][j]);
        acc[b][0] = _mm512_fmadd_ps(v, d0, acc[b][0]);
        acc[b][1] = _mm512_fmadd_ps(v, d1, acc[b][1]);
        acc[b][2] = _mm512_fmadd_ps(v, d2, acc[b][2]);
      }
      d2 = d1;
      d1 = d0;
    };
    for (int64_t j = 0; j < len; ++j) step(j, _mm512_loadu_ps(d + j * ldp));
    step(len, _mm512_setzero_ps());
    step(len + 1, _mm512_setzero_ps());
  }
  for (int b = 0; b < T && b < count; ++b)
    for (int k = 0; k < 3; ++k) {
      float* dst = dwT + (tap[b] + k * tap_step) * ld_dwT;
      _mm512_storeu_ps(dst, _mm512_add_ps(_mm512_loadu_ps(dst), acc[b][k]));
    }
}

}  // namespace

void conv_weight_grad_shift(const float* dyT, int64_t ldp, const float* base, const int64_t* offset,
                            const int64_t* tap, int64_t tap_step, int64_t triples, int64_t len, float* dwT,
                            int64_t ld_dwT, int64_t items, int64_t dy_item, int64_t base_item) {
  constexpr int T = 8;
  for (int64_t b0 = 0; b0 < triples; b0 += T)
    weight_grad_shift_block<T>(dyT, ldp, base, offset + b0, tap + b0, tap_step, std::min<int64_t>(T, triples - b0), len,
                               dwT, ld_dwT, items, dy_item, base_item);
}

// Register tiles of 24 accumulators where the channels allow (4 × 6, 3 × 8, 2 × 12); one vector
// of channels takes 12 taps (12 accumulators: more taps means more window pointers than
// registers, and measured 89 against 153 GFLOP/s with 24).
void conv_weight_grad_outer(const float* dyT, int64_t ldp, int64_t vectors, const float* base,
                            const int64_t* row_offset, int64_t K, int64_t len, float* dwT, int64_t ld_dwT,
                            int64_t items, int64_t dy_item, int64_t base_item) {
  for (int64_t v0 = 0; v0 < vectors; v0 += 4) {
    const int64_t v = std::min<int64_t>(4, vectors - v0);
    const float* d = dyT + 16 * v0;
    float* out = dwT + 16 * v0;
    switch (v) {
      case 4: weight_grad_outer_taps<4, 6>(d, ldp, base, row_offset, K, len, out, ld_dwT, items, dy_item, base_item); break;
      case 3: weight_grad_outer_taps<3, 8>(d, ldp, base, row_offset, K, len, out, ld_dwT, items, dy_item, base_item); break;
      case 2: weight_grad_outer_taps<2, 12>(d, ldp, base, row_offset, K, len, out, ld_dwT, items, dy_item, base_item); break;
      default: weight_grad_outer_taps<1, 12>(d, ldp, base, row_offset, K, len, out, ld_dwT, items, dy_item, base_item);
    }
  }
}

#elif defined(__AVX2__) && defined(__FMA__)

// AVX2 + FMA: the tile runs as 4 × 24 sub-tiles (autodiff/gemm_tile.h); the weight gradient below
// has its own 4-row kernel.
using sl::detail::gemm_tile::lane_mask;
using sl::detail::gemm_tile::micro_kernel;

namespace {

inline float hsum(__m256 v) {
  const __m128 s = _mm_add_ps(_mm256_castps256_ps128(v), _mm256_extractf128_ps(v, 1));
  const __m128 t = _mm_add_ps(s, _mm_movehl_ps(s, s));
  return _mm_cvtss_f32(_mm_add_ss(t, _mm_shuffle_ps(t, t, 1)));
}

}  // namespace

// dw[o][k] += Σ_i dy[o][i] · base[row_offset[k] + i]: 4 rows of dy against 3 windows of the padded
// input, 8 positions per step, 12 accumulators summed once at the end of the range.
void conv_weight_grad_window(const float* dy, int64_t ldy, int64_t M, const float* base, const int64_t* row_offset,
                             int64_t K, int64_t len, float* dw, int64_t items, int64_t dy_item, int64_t base_item) {
  constexpr int64_t kRows = 4;
  const int64_t full = len / 8 * 8;
  const __m256i tail = lane_mask(len - full);
  for (int64_t o0 = 0; o0 < M; o0 += kRows) {
    const int64_t rows = std::min(kRows, M - o0);
    const float* d0[kRows];
    for (int64_t i = 0; i < kRows; ++i) d0[i] = dy + (o0 + std::min(i, rows - 1)) * ldy;  // extra rows dropped
    for (int64_t k0 = 0; k0 < K; k0 += 3) {
      const int64_t cols = std::min<int64_t>(3, K - k0);
#define SL_ROW(i) __m256 a##i##0 = _mm256_setzero_ps(), a##i##1 = a##i##0, a##i##2 = a##i##0;
      SL_ROW(0) SL_ROW(1) SL_ROW(2) SL_ROW(3)
#undef SL_ROW
#define SL_FMA(r, LOAD)                          \
  {                                              \
    const __m256 g = LOAD(d[r] + i);             \
    a##r##0 = _mm256_fmadd_ps(g, v0, a##r##0);   \
    a##r##1 = _mm256_fmadd_ps(g, v1, a##r##1);   \
    a##r##2 = _mm256_fmadd_ps(g, v2, a##r##2);   \
  }
#define SL_STEP(LOAD)                                                  \
  {                                                                    \
    const __m256 v0 = LOAD(x0 + i);                                    \
    const __m256 v1 = LOAD(x1 + i);                                    \
    const __m256 v2 = LOAD(x2 + i);                                    \
    SL_FMA(0, LOAD) SL_FMA(1, LOAD) SL_FMA(2, LOAD) SL_FMA(3, LOAD)    \
  }
#define SL_FULL(p) _mm256_loadu_ps(p)
#define SL_TAIL(p) _mm256_maskload_ps(p, tail)
      for (int64_t t = 0; t < items; ++t) {
        const float* d[kRows];
        for (int64_t r = 0; r < kRows; ++r) d[r] = d0[r] + t * dy_item;
        const float* x0 = base + t * base_item + row_offset[k0];
        const float* x1 = base + t * base_item + row_offset[k0 + std::min<int64_t>(1, cols - 1)];
        const float* x2 = base + t * base_item + row_offset[k0 + std::min<int64_t>(2, cols - 1)];
        int64_t i = 0;
        for (; i < full; i += 8) SL_STEP(SL_FULL)
        if (i < len) SL_STEP(SL_TAIL)
      }
#undef SL_TAIL
#undef SL_FULL
#undef SL_STEP
#undef SL_FMA
      const float sums[3][kRows] = {{hsum(a00), hsum(a10), hsum(a20), hsum(a30)},
                                    {hsum(a01), hsum(a11), hsum(a21), hsum(a31)},
                                    {hsum(a02), hsum(a12), hsum(a22), hsum(a32)}};
      for (int64_t r = 0; r < rows; ++r)
        for (int64_t j = 0; j < cols; ++j) dw[(o0 + r) * K + k0 + j] += sums[j][r];
    }
  }
}

#else

void conv_gemm_window(const float* packed_a, int64_t M, int64_t K, const float* base, const int64_t* row_offset,
                      float* tile) {
  conv_gemm_window_store(packed_a, M, K, base, row_offset, kPanelCols, nullptr, tile, kPanelCols, 0);
}

void conv_gemm_window_store(const float* packed_a, int64_t M, int64_t K, const float* base, const int64_t* row_offset,
                            int64_t n, const float* bias, float* c, int64_t ldc, int64_t /*prefetch*/) {
  for (int64_t m = 0; m < M; ++m)
    for (int64_t j = 0; j < n; ++j) {
      float acc = 0.0f;
      for (int64_t k = 0; k < K; ++k)
        acc += packed_a[((m / kBlockRows) * K + k) * kBlockRows + m % kBlockRows] * base[row_offset[k] + j];
      c[m * ldc + j] = acc + (bias ? bias[m] : 0.0f);
    }
}

double conv_window_cost(int64_t n) { return static_cast<double>(n) / kPanelCols; }

void conv_weight_grad_window(const float* dy, int64_t ldy, int64_t M, const float* base, const int64_t* row_offset,
                             int64_t K, int64_t len, float* dw, int64_t items, int64_t dy_item, int64_t base_item) {
  for (int64_t o = 0; o < M; ++o)
    for (int64_t k = 0; k < K; ++k) {
      float acc = 0.0f;
      for (int64_t t = 0; t < items; ++t)
        for (int64_t i = 0; i < len; ++i) acc += dy[t * dy_item + o * ldy + i] * base[t * base_item + row_offset[k] + i];
      dw[o * K + k] += acc;
    }
}

#endif

#if defined(__AVX512F__) || (defined(__AVX2__) && defined(__FMA__))
// The 8-row blocks of A, each through the tile of autodiff/gemm_tile.h, on a window table.
void conv_gemm_window(const float* packed_a, int64_t M, int64_t K, const float* base, const int64_t* row_offset,
                      float* tile) {
  for (int64_t m0 = 0; m0 < M; m0 += kBlockRows)
    micro_kernel(packed_a + m0 * K, base, [row_offset](int64_t k) { return row_offset[k]; }, K, kPanelCols,
                 std::min(kBlockRows, M - m0), nullptr, tile + m0 * kPanelCols, kPanelCols,
                 m0 == 0 ? kPanelCols : 0);
}

void conv_gemm_window_store(const float* packed_a, int64_t M, int64_t K, const float* base, const int64_t* row_offset,
                            int64_t n, const float* bias, float* c, int64_t ldc, int64_t prefetch) {
  const auto row = [row_offset](int64_t k) { return row_offset[k]; };
  for (int64_t m0 = 0; m0 < M; m0 += kBlockRows) {
    const int64_t rows = std::min(kBlockRows, M - m0);
    const float* const a = packed_a + m0 * K;
    const float* const bm = bias ? bias + m0 : nullptr;
    const int64_t pf = m0 == 0 ? prefetch : 0;
    if (n <= 2 * kPanelCols / 3)
      micro_kernel<decltype(row), 2>(a, base, row, K, n, rows, bm, c + m0 * ldc, ldc, pf);
    else
      micro_kernel(a, base, row, K, n, rows, bm, c + m0 * ldc, ldc, pf);
  }
}

// AVX-512: the 8 × 32 tile does 2/3 of the full tile's FMAs per k, and both are FMA-bound; AVX2
// + FMA: the tile is computed in sub-tiles of 24 columns, each half of the full tile's work.
double conv_window_cost(int64_t n) {
#if defined(__AVX512F__)
  return n <= 2 * kPanelCols / 3 ? 2.0 / 3.0 : 1.0;
#else
  return 0.5 * static_cast<double>((n + 23) / 24);
#endif
}
#endif

}  // namespace sl::nn::detail
