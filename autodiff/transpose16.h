// In-register transpose of a 16 × 16 float block (internal to the GEMM packing and the
// convolution kernels).
//
// Contract: with AVX-512, transpose16(r) turns r[a] lane b into r[b] lane a for a, b < 16, in
// 64 shuffles, and transpose_copy transposes a matrix through it; without AVX-512 this header
// declares nothing.
#pragma once

#if defined(__AVX512F__)
#include <immintrin.h>

#include <algorithm>
#include <cstdint>

namespace sl::detail {

// In-register transpose of a 16 × 16 block: r[a][b] -> r[b][a].
inline void transpose16(__m512 r[16]) {
  __m512 t[16], u[16];
  for (int k = 0; k < 8; ++k) {
    t[2 * k] = _mm512_unpacklo_ps(r[2 * k], r[2 * k + 1]);
    t[2 * k + 1] = _mm512_unpackhi_ps(r[2 * k], r[2 * k + 1]);
  }
  for (int k = 0; k < 4; ++k) {  // u[4k + e], 128-bit lane L: rows 4k..4k+3 at column 4L + e
    u[4 * k] = _mm512_shuffle_ps(t[4 * k], t[4 * k + 2], _MM_SHUFFLE(1, 0, 1, 0));
    u[4 * k + 1] = _mm512_shuffle_ps(t[4 * k], t[4 * k + 2], _MM_SHUFFLE(3, 2, 3, 2));
    u[4 * k + 2] = _mm512_shuffle_ps(t[4 * k + 1], t[4 * k + 3], _MM_SHUFFLE(1, 0, 1, 0));
    u[4 * k + 3] = _mm512_shuffle_ps(t[4 * k + 1], t[4 * k + 3], _MM_SHUFFLE(3, 2, 3, 2));
  }
  for (int e = 0; e < 4; ++e) {
    const __m512 v0 = _mm512_shuffle_f32x4(u[e], u[4 + e], _MM_SHUFFLE(2, 0, 2, 0));
    const __m512 v1 = _mm512_shuffle_f32x4(u[e], u[4 + e], _MM_SHUFFLE(3, 1, 3, 1));
    const __m512 v2 = _mm512_shuffle_f32x4(u[8 + e], u[12 + e], _MM_SHUFFLE(2, 0, 2, 0));
    const __m512 v3 = _mm512_shuffle_f32x4(u[8 + e], u[12 + e], _MM_SHUFFLE(3, 1, 3, 1));
    r[e] = _mm512_shuffle_f32x4(v0, v2, _MM_SHUFFLE(2, 0, 2, 0));
    r[8 + e] = _mm512_shuffle_f32x4(v0, v2, _MM_SHUFFLE(3, 1, 3, 1));
    r[4 + e] = _mm512_shuffle_f32x4(v1, v3, _MM_SHUFFLE(2, 0, 2, 0));
    r[12 + e] = _mm512_shuffle_f32x4(v1, v3, _MM_SHUFFLE(3, 1, 3, 1));
  }
}

// dst[j·dst_step + i] = src[i·src_step + j] for i < ni, j < nj, in 16 × 16 register blocks (the
// reordered copy of a volume whose original innermost axis is stored outermost; im2col panels
// turned into the weight gradient's colᵀ). Element-wise, it is one store per element to a
// different row and was 10% of a 3-D convolution's time.
inline void transpose_copy(const float* src, int64_t src_step, int64_t ni, int64_t nj, float* dst, int64_t dst_step) {
  for (int64_t i0 = 0; i0 < ni; i0 += 16) {
    const int64_t bi = std::min<int64_t>(16, ni - i0);
    const __mmask16 mi = static_cast<__mmask16>((1u << bi) - 1u);
    for (int64_t j0 = 0; j0 < nj; j0 += 16) {
      const int64_t bj = std::min<int64_t>(16, nj - j0);
      const __mmask16 mj = static_cast<__mmask16>((1u << bj) - 1u);
      __m512 r[16];
      for (int64_t a = 0; a < 16; ++a)
        r[a] = a < bi ? _mm512_maskz_loadu_ps(mj, src + (i0 + a) * src_step + j0) : _mm512_setzero_ps();
      transpose16(r);
      for (int64_t b = 0; b < bj; ++b) _mm512_mask_storeu_ps(dst + (j0 + b) * dst_step + i0, mi, r[b]);
    }
  }
}

}  // namespace sl::detail
#endif
