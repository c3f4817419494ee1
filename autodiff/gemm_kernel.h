// The register-blocked float GEMM shared by matmul (autodiff/matmul.cpp) and the convolutions
// (nn/functional/conv_microkernel.h).
//
// Contract: C[M, n] = A[M, K] · B[K, n] (+ bias[m]) for one panel of n <= kPanelCols columns,
// where A was packed once by pack_rows into row blocks [ceil(M / kBlockRows)][K][kBlockRows]
// and B is a panel whose row k starts at b_panel + k·ldb; 48 floats are read per row of B
// whatever n (columns past n are ignored, so the caller gives the last panel of a matrix slack or
// a padded copy). C has leading dimension ldc. Each output element is one fixed sequence of FMAs
// over k = 0..K-1 (autodiff/gemm_tile.h), so the result does not depend on threads, on which
// panel it is computed in, or on AVX-512 against AVX2 + FMA. gemm_kernel_available() is false
// without either; the panel functions then run a plain loop (other bits) and callers that care
// for speed use Eigen instead.
// Why a kernel of our own beside Eigen: the 8 × 48 tile keeps 24 AVX-512 accumulators busy with
// 3 loads and 8 broadcasts per 24 FMAs, where Eigen 3.4's 48 × 4 tile needs 3 loads and 4 broadcasts per 12 FMAs
// (1024³: 214 against 165 GFLOP/s on an AMD EPYC of family 25, 2 threads), and the convolutions
// write their im2col panels straight into the layout it streams.
#pragma once
#include <cstdint>
#include <memory>

namespace sl::detail {

constexpr int64_t kBlockRows = 8;
constexpr int64_t kPanelCols = 48;

bool gemm_kernel_available();

// 64-byte aligned float scratch (contents unspecified). Blocks of 1 MiB and more come from the
// buffer cache (autodiff/buffer_cache.h): packed operands and padded copies have the same sizes
// step after step, and fresh pages would fault and be zeroed on each call (a quarter of the
// transform of ResNet-18's 512-channel weights).
struct CachedFloatsDeleter {
  size_t capacity = 0;
  void operator()(float* p) const;
};
using CachedFloats = std::unique_ptr<float[], CachedFloatsDeleter>;
CachedFloats cached_floats(int64_t floats);

// Zero-padded row blocks of A. The storage is written once, block by block in parallel, without
// a zero fill first: deep layers have megabytes of weights and only a few dozen positions per
// weight to amortise the packing over.
struct PackedRows {
  CachedFloats buffer;
  const float* data() const { return buffer.get(); }
};
// A [M, K] row-major (leading dimension K).
PackedRows pack_rows(const float* a, int64_t M, int64_t K);
// A = Wᵀ for w [O, R] row-major: A[r][o] = w[o][r] (R rows of O).
PackedRows pack_rows_transposed(const float* w, int64_t O, int64_t R);

// ldb: the row pitch of B (a window of a wider column block; 48 columns are read per row).
void gemm_panel(const float* packed_a, int64_t M, int64_t K, const float* b_panel, int64_t n, const float* bias,
                float* c, int64_t ldc, int64_t ldb = kPanelCols);

// gemm_panel for a narrow panel of n <= 32 columns, on an 8 × 32 tile: two thirds of the
// 48-column tile's work where only 32 columns exist (the same FMA sequence per output, so the same
// bits). Reads 48 floats per row of B with AVX2 (give the panel 16 floats of slack), 32 with AVX-512.
void gemm_panel_narrow(const float* packed_a, int64_t M, int64_t K, const float* b_panel, int64_t n,
                       const float* bias, float* c, int64_t ldc, int64_t ldb);

}  // namespace sl::detail
