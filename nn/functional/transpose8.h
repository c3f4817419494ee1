// In-register transpose of an 8 × 8 float block (internal to the convolution kernels).
//
// Contract: with AVX2, transpose8(r) turns r[a] lane b into r[b] lane a for a, b < 8, in 24
// shuffles; it only moves bits. Without AVX2 this header declares nothing.
#pragma once

#if defined(__AVX2__)
#include <immintrin.h>

namespace sl::nn::detail {

inline void transpose8(__m256 r[8]) {
  __m256 t[8], u[8];
  for (int k = 0; k < 4; ++k) {  // t[2k], t[2k+1]: rows 2k and 2k+1 interleaved
    t[2 * k] = _mm256_unpacklo_ps(r[2 * k], r[2 * k + 1]);
    t[2 * k + 1] = _mm256_unpackhi_ps(r[2 * k], r[2 * k + 1]);
  }
  for (int k = 0; k < 2; ++k) {  // u[4k + e], 128-bit lane L: rows 4k..4k+3 at column 4L + e
    u[4 * k] = _mm256_shuffle_ps(t[4 * k], t[4 * k + 2], _MM_SHUFFLE(1, 0, 1, 0));
    u[4 * k + 1] = _mm256_shuffle_ps(t[4 * k], t[4 * k + 2], _MM_SHUFFLE(3, 2, 3, 2));
    u[4 * k + 2] = _mm256_shuffle_ps(t[4 * k + 1], t[4 * k + 3], _MM_SHUFFLE(1, 0, 1, 0));
    u[4 * k + 3] = _mm256_shuffle_ps(t[4 * k + 1], t[4 * k + 3], _MM_SHUFFLE(3, 2, 3, 2));
  }
  for (int e = 0; e < 4; ++e) {  // low lanes give columns 0-3, high lanes columns 4-7
    r[e] = _mm256_permute2f128_ps(u[e], u[4 + e], 0x20);
    r[4 + e] = _mm256_permute2f128_ps(u[e], u[4 + e], 0x31);
  }
}

}  // namespace sl::nn::detail
#endif
