// The register tile of the packed float GEMM (internal to autodiff/gemm_kernel.cpp and
// nn/functional/conv_microkernel.cpp, which also runs it on the shifted windows of an implicit
// convolution).
//
// Contract: micro_kernel(a, b, row, K, n, rows, bias, c, ldc, prefetch) computes, for i < rows
// (<= kBlockRows) and j < n (<= 16·V), c[i·ldc + j] = Σ_k a[k·kBlockRows + i] · b[row(k) + j]
// (+ bias[i]) as one fixed FMA sequence over k = 0..K-1, so AVX-512 and AVX2 give the same bits.
// a is one packed row block (autodiff/gemm_kernel.h); row(k) is the offset of B's row k (a panel
// pitch or an implicit-GEMM offset table). Each row of B is read for 16·V columns (AVX2: in
// sub-tiles of 24), whatever n. Declares nothing without AVX2 + FMA.
#pragma once
#include <algorithm>
#include <cstdint>

#include "autodiff/gemm_kernel.h"

#if defined(__AVX512F__) || (defined(__AVX2__) && defined(__FMA__))
#include <immintrin.h>
#endif

namespace sl::detail::gemm_tile {

#if defined(__AVX512F__)

constexpr int64_t kNearPrefetch = 24;  // taps (about 300 cycles at 2 FMAs per cycle)

// One 8 × 48 tile: 24 named accumulators, so that they stay in registers (an array of them
// made GCC spill every accumulator on each k step).
// Row k of B starts at b + row(k): a packed panel (row(k) = 48·k) or a shifted window of a
// padded input (row(k) = offset table), autodiff/gemm_kernel.h.
// prefetch > 0 touches, for every k, the window `prefetch` floats ahead (the next panel's, into
// L2), so that its lines come from L3 while this panel computes: a padded 3-D input has one
// stream per (channel, kz, ky), too many for the hardware prefetchers to follow. It also brings
// the window kNearPrefetch taps ahead into L1: the next panel's lines fetched a whole panel early
// (thousands of cycles with 4 Winograd components) are presumably evicted from L1 before use on an AVX-512
// Xeon (48 KiB L1d). Measured there, 1 thread, CPU time, 4 alternating rounds under load:
// forward 2×32×32³ 20.2 → 19.7 ms, 1×16×64×64×16 7.0 → 6.0 ms, 8×64×64² 13.0 → 12.5 ms
// (24 taps ahead: 12 and 16 gained less, 32 about the same).
// V: column vectors of 16 (3: the 8 × 48 tile; 2: an 8 × 32 one for narrow panels, whose third
// accumulators, loads and stores the compiler drops).
template <class Row, int V = 3>
inline void micro_kernel(const float* a, const float* b, Row row, int64_t K, int64_t n, int64_t rows,
                         const float* bias, float* c, int64_t ldc, int64_t prefetch = 0) {
  static_assert(V == 2 || V == 3);
#define SL_ROW(i) __m512 c##i##0 = _mm512_setzero_ps(), c##i##1 = c##i##0, c##i##2 = c##i##0;
  SL_ROW(0) SL_ROW(1) SL_ROW(2) SL_ROW(3) SL_ROW(4) SL_ROW(5) SL_ROW(6) SL_ROW(7)
#undef SL_ROW
  for (int64_t k = 0; k < K; ++k) {
    const float* bk = b + row(k);
    if (prefetch) {
      _mm_prefetch(reinterpret_cast<const char*>(bk + prefetch), _MM_HINT_T1);
      _mm_prefetch(reinterpret_cast<const char*>(bk + prefetch + 16), _MM_HINT_T1);
      _mm_prefetch(reinterpret_cast<const char*>(bk + prefetch + 32), _MM_HINT_T1);
      _mm_prefetch(reinterpret_cast<const char*>(bk + prefetch + 47), _MM_HINT_T1);
      if (k + kNearPrefetch < K) {
        const float* bn = b + row(k + kNearPrefetch);
        _mm_prefetch(reinterpret_cast<const char*>(bn), _MM_HINT_T0);
        _mm_prefetch(reinterpret_cast<const char*>(bn + 16), _MM_HINT_T0);
        _mm_prefetch(reinterpret_cast<const char*>(bn + 32), _MM_HINT_T0);
        _mm_prefetch(reinterpret_cast<const char*>(bn + 47), _MM_HINT_T0);
      }
    }
    const __m512 b0 = _mm512_loadu_ps(bk);
    const __m512 b1 = _mm512_loadu_ps(bk + 16);
    const __m512 b2 = V == 3 ? _mm512_loadu_ps(bk + 32) : _mm512_setzero_ps();
    const float* ak = a + k * kBlockRows;
#define SL_FMA(i)                                               \
  {                                                             \
    const __m512 ai = _mm512_set1_ps(ak[i]);                    \
    c##i##0 = _mm512_fmadd_ps(ai, b0, c##i##0);                 \
    c##i##1 = _mm512_fmadd_ps(ai, b1, c##i##1);                 \
    if constexpr (V == 3) c##i##2 = _mm512_fmadd_ps(ai, b2, c##i##2); \
  }
    SL_FMA(0) SL_FMA(1) SL_FMA(2) SL_FMA(3) SL_FMA(4) SL_FMA(5) SL_FMA(6) SL_FMA(7)
#undef SL_FMA
  }
  __mmask16 mask[3];
  for (int j = 0; j < 3; ++j) {
    const int64_t cols = j < V ? std::clamp<int64_t>(n - 16 * j, 0, 16) : 0;
    mask[j] = static_cast<__mmask16>((1u << cols) - 1u);
  }
#define SL_STORE(i)                                                                  \
  if (i < rows) {                                                                    \
    const __m512 bi = _mm512_set1_ps(bias ? bias[i] : 0.0f);                         \
    _mm512_mask_storeu_ps(c + i * ldc, mask[0], _mm512_add_ps(c##i##0, bi));         \
    _mm512_mask_storeu_ps(c + i * ldc + 16, mask[1], _mm512_add_ps(c##i##1, bi));    \
    if constexpr (V == 3) _mm512_mask_storeu_ps(c + i * ldc + 32, mask[2], _mm512_add_ps(c##i##2, bi)); \
  }
  SL_STORE(0) SL_STORE(1) SL_STORE(2) SL_STORE(3) SL_STORE(4) SL_STORE(5) SL_STORE(6) SL_STORE(7)
#undef SL_STORE
}

#elif defined(__AVX2__) && defined(__FMA__)

// AVX2 + FMA: 16 vector registers of 8 floats, so the 8 × 48 tile is computed as four 4 × 24
// sub-tiles of 12 accumulators (plus 3 B vectors and one broadcast). Every output element is the
// same FMA sequence over k = 0..K-1 as with AVX-512, so both give the same bits.
// Lanes [0, n) of a row of 8 (n <= 8).
inline __m256i lane_mask(int64_t n) {
  alignas(32) static const int32_t ramp[8] = {0, 1, 2, 3, 4, 5, 6, 7};
  return _mm256_cmpgt_epi32(_mm256_set1_epi32(static_cast<int32_t>(std::clamp<int64_t>(n, 0, 8))),
                            _mm256_load_si256(reinterpret_cast<const __m256i*>(ramp)));
}

// Rows r0..r0+3 (of a packed block of 8) × columns c0..c0+23 of the tile.
template <class Row>
inline void sub_kernel(const float* a, const float* b, Row row, int64_t K, int64_t c0, int64_t n, int64_t rows,
                       const float* bias, float* c, int64_t ldc, int64_t prefetch) {
#define SL_ROW(i) __m256 c##i##0 = _mm256_setzero_ps(), c##i##1 = c##i##0, c##i##2 = c##i##0;
  SL_ROW(0) SL_ROW(1) SL_ROW(2) SL_ROW(3)
#undef SL_ROW
  for (int64_t k = 0; k < K; ++k) {
    const float* bk = b + row(k) + c0;
    if (prefetch) {
      _mm_prefetch(reinterpret_cast<const char*>(bk + prefetch), _MM_HINT_T0);
      _mm_prefetch(reinterpret_cast<const char*>(bk + prefetch + 16), _MM_HINT_T0);
      _mm_prefetch(reinterpret_cast<const char*>(bk + prefetch + 32), _MM_HINT_T0);
    }
    const __m256 b0 = _mm256_loadu_ps(bk);
    const __m256 b1 = _mm256_loadu_ps(bk + 8);
    const __m256 b2 = _mm256_loadu_ps(bk + 16);
    const float* ak = a + k * kBlockRows;
#define SL_FMA(i)                                  \
  {                                                \
    const __m256 ai = _mm256_broadcast_ss(ak + i); \
    c##i##0 = _mm256_fmadd_ps(ai, b0, c##i##0);    \
    c##i##1 = _mm256_fmadd_ps(ai, b1, c##i##1);    \
    c##i##2 = _mm256_fmadd_ps(ai, b2, c##i##2);    \
  }
    SL_FMA(0) SL_FMA(1) SL_FMA(2) SL_FMA(3)
#undef SL_FMA
  }
  const __m256i m0 = lane_mask(n - c0), m1 = lane_mask(n - c0 - 8), m2 = lane_mask(n - c0 - 16);
#define SL_STORE(i)                                                            \
  if (i < rows) {                                                              \
    const __m256 bi = _mm256_set1_ps(bias ? bias[i] : 0.0f);                   \
    float* ci = c + i * ldc + c0;                                              \
    _mm256_maskstore_ps(ci, m0, _mm256_add_ps(c##i##0, bi));                   \
    _mm256_maskstore_ps(ci + 8, m1, _mm256_add_ps(c##i##1, bi));               \
    _mm256_maskstore_ps(ci + 16, m2, _mm256_add_ps(c##i##2, bi));              \
  }
  SL_STORE(0) SL_STORE(1) SL_STORE(2) SL_STORE(3)
#undef SL_STORE
}

// V is the AVX-512 kernel's column-vector count; here the sub-tiles of 24 columns cover n (a
// narrow 32-column panel reads 48 columns per row: gemm_panel_narrow's contract).
template <class Row, int V = 3>
inline void micro_kernel(const float* a, const float* b, Row row, int64_t K, int64_t n, int64_t rows,
                         const float* bias, float* c, int64_t ldc, int64_t prefetch = 0) {
  for (int64_t h = 0; h < 2 && 4 * h < rows; ++h)
    for (int64_t c0 = 0; c0 < n; c0 += 24)
      sub_kernel(a + 4 * h, b, row, K, c0, n, rows - 4 * h, bias ? bias + 4 * h : nullptr, c + 4 * h * ldc, ldc,
                 h == 0 && c0 == 0 ? prefetch : 0);
}

#endif

}  // namespace sl::detail::gemm_tile
