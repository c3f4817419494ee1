#include "autodiff/gemm_kernel.h"

#include <algorithm>

#include "autodiff/buffer_cache.h"
#include "autodiff/gemm_tile.h"
#include "autodiff/transpose16.h"
#include "util/parallel.h"

namespace sl::detail {

namespace {
// Row blocks per parallel chunk: at least ~64 K floats moved per chunk (small packs stay on the
// calling thread). Chunking never changes the packed bits.
int64_t grain(int64_t floats_per_block) { return std::max<int64_t>(1, (int64_t{1} << 16) / std::max<int64_t>(floats_per_block, 1)); }
}  // namespace

void CachedFloatsDeleter::operator()(float* p) const { release_buffer({p, capacity}); }

CachedFloats cached_floats(int64_t floats) {
  const size_t bytes = (static_cast<size_t>(floats) * sizeof(float) + 63) / 64 * 64;
  const Buffer b = acquire_buffer(bytes == 0 ? 64 : bytes);  // throws when memory runs out
  return CachedFloats(static_cast<float*>(b.data), CachedFloatsDeleter{b.capacity});
}

PackedRows pack_rows(const float* a, int64_t M, int64_t K) {
  const int64_t blocks = (M + kBlockRows - 1) / kBlockRows;
  PackedRows packed{cached_floats(blocks * K * kBlockRows)};
  parallel_for(blocks, grain(K * kBlockRows), [&](int64_t b0, int64_t b1) {
    for (int64_t blk = b0; blk < b1; ++blk) {
      float* dst = packed.buffer.get() + blk * K * kBlockRows;
      const float* src = a + blk * kBlockRows * K;
      const int64_t rows = std::min(kBlockRows, M - blk * kBlockRows);
      int64_t k0 = 0;
#if defined(__AVX512F__)
      static_assert(kBlockRows == 8);
      // 8 rows × 32 columns per step: r[i] holds columns k0..k0+15 of row i, r[8 + i] columns
      // k0+16..k0+31; after the transpose r[j] = {rows 0-7 at column k0 + j, rows 0-7 at k0 + 16 + j}.
      if (rows == kBlockRows)
        for (; k0 + 32 <= K; k0 += 32) {
          __m512 r[16];
          for (int i = 0; i < 8; ++i) {
            r[i] = _mm512_loadu_ps(src + i * K + k0);
            r[8 + i] = _mm512_loadu_ps(src + i * K + k0 + 16);
          }
          transpose16(r);
          for (int j = 0; j < 16; ++j) {
            _mm256_storeu_ps(dst + (k0 + j) * kBlockRows, _mm512_castps512_ps256(r[j]));
            _mm256_storeu_ps(dst + (k0 + 16 + j) * kBlockRows,
                             _mm256_castpd_ps(_mm512_extractf64x4_pd(_mm512_castps_pd(r[j]), 1)));
          }
        }
#endif
      for (int64_t k = k0; k < K; ++k)
        for (int64_t i = 0; i < kBlockRows; ++i) dst[k * kBlockRows + i] = i < rows ? src[i * K + k] : 0.0f;
    }
  });
  return packed;
}

PackedRows pack_rows_transposed(const float* w, int64_t O, int64_t R) {
  const int64_t blocks = (R + kBlockRows - 1) / kBlockRows;
  PackedRows packed{cached_floats(blocks * O * kBlockRows)};
  parallel_for(blocks, grain(O * kBlockRows), [&](int64_t b0, int64_t b1) {
    for (int64_t blk = b0; blk < b1; ++blk) {
      const int64_t r0 = blk * kBlockRows, rows = std::min(kBlockRows, R - r0);
      float* dst = packed.buffer.get() + blk * O * kBlockRows;
      for (int64_t o = 0; o < O; ++o)
        for (int64_t i = 0; i < kBlockRows; ++i) dst[o * kBlockRows + i] = i < rows ? w[o * R + r0 + i] : 0.0f;
    }
  });
  return packed;
}

#if defined(__AVX512F__) || (defined(__AVX2__) && defined(__FMA__))

bool gemm_kernel_available() { return true; }

namespace {
struct RowPitch {  // row k of a packed panel
  int64_t ldb;
  int64_t operator()(int64_t k) const { return k * ldb; }
};
}  // namespace

// The 8-row blocks of A, each through the tile of autodiff/gemm_tile.h.
void gemm_panel(const float* packed_a, int64_t M, int64_t K, const float* b_panel, int64_t n, const float* bias,
                float* c, int64_t ldc, int64_t ldb) {
  for (int64_t m0 = 0; m0 < M; m0 += kBlockRows)
    gemm_tile::micro_kernel(packed_a + m0 * K, b_panel, RowPitch{ldb}, K, n, std::min(kBlockRows, M - m0),
                            bias ? bias + m0 : nullptr, c + m0 * ldc, ldc);
}

void gemm_panel_narrow(const float* packed_a, int64_t M, int64_t K, const float* b_panel, int64_t n,
                       const float* bias, float* c, int64_t ldc, int64_t ldb) {
  for (int64_t m0 = 0; m0 < M; m0 += kBlockRows)
    gemm_tile::micro_kernel<RowPitch, 2>(packed_a + m0 * K, b_panel, RowPitch{ldb}, K, n,
                                         std::min(kBlockRows, M - m0), bias ? bias + m0 : nullptr, c + m0 * ldc,
                                         ldc);
}

#else

bool gemm_kernel_available() { return false; }

void gemm_panel(const float* packed_a, int64_t M, int64_t K, const float* b_panel, int64_t n,
                     const float* bias, float* c, int64_t ldc, int64_t ldb) {
  for (int64_t m = 0; m < M; ++m)
    for (int64_t j = 0; j < n; ++j) {
      float acc = 0.0f;
      for (int64_t k = 0; k < K; ++k)
        acc += packed_a[((m / kBlockRows) * K + k) * kBlockRows + m % kBlockRows] * b_panel[k * ldb + j];
      c[m * ldc + j] = acc + (bias ? bias[m] : 0.0f);
    }
}

void gemm_panel_narrow(const float* packed_a, int64_t M, int64_t K, const float* b_panel, int64_t n,
                            const float* bias, float* c, int64_t ldc, int64_t ldb) {
  gemm_panel(packed_a, M, K, b_panel, n, bias, c, ldc, ldb);
}

#endif

}  // namespace sl::detail
