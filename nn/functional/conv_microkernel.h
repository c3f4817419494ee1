// The convolution kernels on the packed float GEMM of autodiff/gemm_kernel.h (internal to
// nn/functional/conv.cpp): the implicit GEMM over shifted windows and the weight gradients.
//
// Contract: as autodiff/gemm_kernel.h for the packed operand and the tile (the same FMA sequence
// per output element with AVX-512 and with AVX2 + FMA, so the bits match); without either,
// gemm_kernel_available() is false and conv.cpp uses autodiff's Eigen GEMM.
// Why not Eigen here: im2col can write its panel directly in the layout the micro-kernel
// streams, which saves Eigen's second packing copy of the column matrix, and the 8×48 tile keeps
// 24 AVX-512 accumulators busy for the 16-64 output channels typical of these networks.
#pragma once
#include <cstdint>
#include <memory>
#include <vector>

#include "autodiff/gemm_kernel.h"
#include "autodiff/transpose16.h"

namespace sl::nn::detail {

using sl::detail::cached_floats;
using sl::detail::CachedFloats;
using sl::detail::gemm_kernel_available;
using sl::detail::gemm_panel;
using sl::detail::gemm_panel_narrow;
using sl::detail::kBlockRows;
using sl::detail::kPanelCols;
using sl::detail::pack_rows;
using sl::detail::pack_rows_transposed;
using sl::detail::PackedRows;
#if defined(__AVX512F__)
using sl::detail::transpose16;
using sl::detail::transpose_copy;
#endif

// pack_rows of the flipped, transposed kernel that turns a stride-1 convolution's input
// gradient into a forward convolution: A[c][o·taps + t] = w[o][c][taps - 1 - t] for w [O, C, taps],
// in one pass over w (no intermediate transposed copy).
PackedRows pack_weights_flipped(const float* w, int64_t O, int64_t C, int64_t taps);

// Implicit GEMM for stride-1 convolutions: B[k][j] = base[row_offset[k] + j] for j < 48, i.e.
// every row of B is a shifted window of a zero-padded input, so no column matrix is built.
// Writes all 48 columns of tile [M][48] (the caller keeps the valid ones).
void conv_gemm_window(const float* packed_a, int64_t M, int64_t K, const float* base, const int64_t* row_offset,
                      float* tile);

// conv_gemm_window for the first n <= 48 columns, written straight to the output: for m < M and
// j < n, c[m·ldc + j] = Σ_k A[m][k] · base[row_offset[k] + j] (+ bias[m] when bias is not null),
// with the same FMA sequence per element as conv_gemm_window (so the same bits as its tile plus
// the bias). With AVX-512, n <= 32 runs the 8 × 32 tile. Reads 48 columns of every window, as
// conv_gemm_window does. prefetch: as the tile's (autodiff/gemm_tile.h), for the first row block.
void conv_gemm_window_store(const float* packed_a, int64_t M, int64_t K, const float* base, const int64_t* row_offset,
                            int64_t n, const float* bias, float* c, int64_t ldc, int64_t prefetch);

// The run time of conv_gemm_window_store for n columns relative to a full 48-column call, from
// the instruction mix of the tile this build runs (both tiles are FMA-bound).
double conv_window_cost(int64_t n);

// Weight gradient of a stride-1 convolution on the same windows: for o < M and k < K,
// dw[o·K + k] += Σ_{t < items} Σ_{i < len} dy[t·dy_item + o·ldy + i] · base[t·base_item + row_offset[k] + i],
// where dy is the output gradient laid out on the padded pitch (zeros at dropped positions).
// Several items (batch items of a layer with few positions each) share one set of accumulators,
// reduced once: per item the sums would be a few vector steps long. Reads nothing past
// base[t·base_item + row_offset[k] + len - 1].
void conv_weight_grad_window(const float* dy, int64_t ldy, int64_t M, const float* base, const int64_t* row_offset,
                             int64_t K, int64_t len, float* dw, int64_t items = 1, int64_t dy_item = 0,
                             int64_t base_item = 0);

// The weight gradient of conv_weight_grad_window as outer products (AVX-512 only): with dy
// transposed to dyT[i][o] (ldp floats per position, `vectors` · 16 channels, zeros past the real
// ones), for k < K and o < 16·vectors,
//   dwT[k·ld_dwT + o] += Σ_{t < items} Σ_{i < len} base[t·base_item + row_offset[k] + i] · dyT[t·dy_item + i·ldp + o].
// Each accumulator holds one tap's gradient for 16 channels, so nothing is reduced across lanes
// and every load is a broadcast or a whole vector of dyT: 190 against 120 GFLOP/s for the window
// kernel on an AVX-512 Xeon (standalone, 64 channels). Each dwT element is one fixed FMA sequence
// over (t, i), then one addition.
void conv_weight_grad_outer(const float* dyT, int64_t ldp, int64_t vectors, const float* base,
                            const int64_t* row_offset, int64_t K, int64_t len, float* dwT, int64_t ld_dwT,
                            int64_t items = 1, int64_t dy_item = 0, int64_t base_item = 0);

// conv_weight_grad_outer for one vector of channels (dyT rows of 16 floats, ldp apart) on taps
// grouped in triples whose windows are 1, 2 floats apart (3 undilated taps along the innermost
// storage axis): triple b is taps tap[b] + k·tap_step, k < 3, with windows at base + offset[b] + k.
// One broadcast of an input value then feeds all three taps (the dy of positions j, j − 1, j − 2
// stay in registers): 1 broadcast per 3 FMAs instead of 1 per FMA, which held the one-vector tile
// at 153 GFLOP/s. Each dwT element is one fixed FMA sequence over positions in order (plus
// products with the zeros outside [0, len)), then one addition.
void conv_weight_grad_shift(const float* dyT, int64_t ldp, const float* base, const int64_t* offset,
                            const int64_t* tap, int64_t tap_step, int64_t triples, int64_t len, float* dwT,
                            int64_t ld_dwT, int64_t items = 1, int64_t dy_item = 0, int64_t base_item = 0);

}  // namespace sl::nn::detail
