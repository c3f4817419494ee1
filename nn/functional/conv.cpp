#include "nn/functional/conv.h"

#include <algorithm>
#include <type_traits>
#include <vector>

#include "autodiff/matmul.h"
#include "autodiff/tape.h"
#include "nn/functional/conv_geometry.h"
#include "nn/functional/conv_implicit_gemm.h"
#include "nn/functional/conv_microkernel.h"
#include "nn/functional/conv_winograd.h"
#include "nn/functional/group_sums.h"
#include "autodiff/transpose16.h"
#include "nn/functional/work_grain.h"
#include "util/parallel.h"

namespace sl::nn {
namespace {
using detail::ConvGeometry;

bool is_pointwise(const ConvGeometry& g) {
  for (int a = 0; a < 3; ++a)
    if (g.k[a] != 1 || g.stride[a] != 1 || g.pad[a] != 0) return false;
  return true;
}

// The column blocks of the im2col GEMMs: a spatial tile of one batch item or, when an item has
// fewer output positions than a tile, several whole items side by side. Deep layers (a few dozen
// positions, thousands of taps) would otherwise run GEMMs a few dozen columns wide, where
// packing overheads dominate. Fixed by the shapes only.
struct ColumnBlocks {
  int64_t N = 0, P = 0, tile = 0, tiles_per_item = 1, items_per_block = 1, count = 0;
  struct Block {
    int64_t n0, n1, p0, cnt;  // items [n0, n1), positions [p0, p0 + cnt) of each
    int64_t cols() const { return (n1 - n0) * cnt; }
  };
  Block at(int64_t b) const {
    if (items_per_block == 1) {
      const int64_t n = b / tiles_per_item, p0 = (b % tiles_per_item) * tile;
      return {n, n + 1, p0, std::min(tile, P - p0)};
    }
    return {b * items_per_block, std::min(N, (b + 1) * items_per_block), 0, P};
  }
};

template <class T>
ColumnBlocks column_blocks(const ConvGeometry& g) {
  ColumnBlocks cb;
  cb.N = g.N;
  cb.P = g.out_plane();
  const int64_t budget = (1 << 20) / static_cast<int64_t>(sizeof(T));  // col block near one L2
  cb.tile = std::max<int64_t>(budget / std::max<int64_t>(g.rows(), 1), 512);
  cb.tile = (cb.tile + 15) / 16 * 16;
  if (cb.P >= cb.tile) {
    cb.tiles_per_item = (cb.P + cb.tile - 1) / cb.tile;
    cb.count = g.N * cb.tiles_per_item;
  } else {
    cb.items_per_block = std::max<int64_t>(1, cb.tile / std::max<int64_t>(cb.P, 1));
    cb.count = (g.N + cb.items_per_block - 1) / cb.items_per_block;
  }
  return cb;
}

// x split into row phases for strided im2col (see im2col.h); empty when stride[2] == 1.
template <class T>
struct PhasedInput {
  detail::PhasedRows rows;
  int64_t rows_per_item = 0;
  std::vector<T> data;
};

template <class T>
PhasedInput<T> phase_input(const ConvGeometry& g, const T* x) {
  PhasedInput<T> p;
  p.rows = detail::phased_rows(g);
  p.rows_per_item = g.C * g.in[0] * g.in[1];
  if (p.rows.stride == 1) return p;
  p.data.resize(static_cast<size_t>(g.N * p.rows_per_item * p.rows.row_pitch()));
  parallel_for(g.N * p.rows_per_item, detail::grain_for(g.in[2]), [&](int64_t r0, int64_t r1) {
    detail::split_phases(x + r0 * g.in[2], r1 - r0, g.in[2], p.rows, p.data.data() + r0 * p.rows.row_pitch());
  });
  return p;
}

// col[r][(n - n0)·cnt + i] for the items and positions of block b (leading dim blk.cols()).
// Items in parallel when called outside a parallel region (a block holding all items).
template <class T>
void im2col_block(const ConvGeometry& g, const ColumnBlocks::Block& blk, const T* x, const PhasedInput<T>& ph,
                  T* col) {
  parallel_for(blk.n1 - blk.n0, detail::grain_for(g.rows() * blk.cnt), [&](int64_t i0, int64_t i1) {
    for (int64_t n = blk.n0 + i0; n < blk.n0 + i1; ++n) {
      T* dst = col + (n - blk.n0) * blk.cnt;
      if (ph.data.empty()) {
        detail::im2col_tile(x + n * g.C * g.in_plane(), g, blk.p0, blk.cnt, dst, blk.cols());
      } else {
        detail::im2col_tile_phased(ph.data.data() + n * ph.rows_per_item * ph.rows.row_pitch(), g, ph.rows, blk.p0,
                                   blk.cnt, dst, blk.cols());
      }
    }
  });
}

// dst[o][(n - n0)·cnt + i] = src[n][o][p0 + i]: a [rows, cols] view of a per-item tensor.
template <class T>
void gather_block(const ColumnBlocks::Block& blk, const T* src, int64_t rows, int64_t P, T* dst) {
  for (int64_t n = blk.n0; n < blk.n1; ++n)
    for (int64_t o = 0; o < rows; ++o)
      std::copy(src + (n * rows + o) * P + blk.p0, src + (n * rows + o) * P + blk.p0 + blk.cnt,
                dst + o * blk.cols() + (n - blk.n0) * blk.cnt);
}

// Output positions per image below which the implicit-GEMM and panel kernels leave too much of
// each 48-column panel and of each weight-gradient reduction idle; the batch-folded GEMM wins.
constexpr int64_t kMinDirectPositions = 96;

// Float on AVX-512: im2col writes a run of 48-column panels of one item (as many as keep the
// column block near 256 KiB) in one call, the micro-kernel then streams each panel as a window of
// that block, and the packed weights are shared by all tasks. One im2col call per run rather than
// per panel: with few rows (a 7×7 stem on 3 channels) im2col's per-row set-up cost otherwise
// rivals the GEMM.
void conv_forward_panels(const ConvGeometry& g, const float* x, const float* packed, const float* b, float* y) {
  constexpr int64_t kCols = detail::kPanelCols;
  const int64_t P = g.out_plane(), R = g.rows();
  const int64_t run = std::clamp<int64_t>((int64_t{1} << 16) / std::max<int64_t>(R, 1) / kCols, 1, 8) * kCols;
  const int64_t tile = 8 * kCols, tiles = (P + tile - 1) / tile;
  const PhasedInput<float> phased = phase_input(g, x);
  const detail::PhasedRows& ph = phased.rows;
  parallel_for(g.N * tiles, detail::grain_for(g.O * R * tile), [&](int64_t t0, int64_t t1) {
    std::vector<float> col(static_cast<size_t>(R * run), 0.0f);  // columns past a short run: stale, never stored
    for (int64_t t = t0; t < t1; ++t) {
      const int64_t n = t / tiles, end = std::min(P, (t % tiles + 1) * tile);
      const float* xn = x + n * g.C * g.in_plane();
      for (int64_t q0 = (t % tiles) * tile; q0 < end; q0 += run) {
        const int64_t len = std::min(run, end - q0);
        if (ph.stride > 1) {
          detail::im2col_tile_phased(phased.data.data() + n * phased.rows_per_item * ph.row_pitch(), g, ph, q0, len,
                                     col.data(), run);
        } else {
          detail::im2col_tile(xn, g, q0, len, col.data(), run);
        }
        for (int64_t q = q0; q < q0 + len; q += kCols)
          detail::gemm_panel(packed, g.O, R, col.data() + (q - q0), std::min(kCols, q0 + len - q), b,
                                  y + n * g.O * P + q, P, run);
      }
    }
  });
}

// Panel p of the batch-folded column matrix: im2col columns p·48 .. of all items' positions in
// order (column n·P + q), [R][48], one run of positions of one item per call.
void folded_panel(const ConvGeometry& g, const float* x, const PhasedInput<float>& phased, int64_t p, float* panel) {
  constexpr int64_t kCols = detail::kPanelCols;
  const int64_t P = g.out_plane(), c1 = std::min(g.N * P, (p + 1) * kCols);
  const detail::PhasedRows& ph = phased.rows;
  for (int64_t c = p * kCols; c < c1;) {
    const int64_t n = c / P, q = c % P, cnt = std::min(P - q, c1 - c);
    if (ph.stride > 1) {
      detail::im2col_tile_phased(phased.data.data() + n * phased.rows_per_item * ph.row_pitch(), g, ph, q, cnt,
                                 panel + (c - p * kCols), kCols);
    } else {
      detail::im2col_tile(x + n * g.C * g.in_plane(), g, q, cnt, panel + (c - p * kCols), kCols);
    }
    c += cnt;
  }
}

// Float on AVX-512, fewer than kMinDirectPositions positions per image (a ResNet's deep stages:
// 4×8 positions, 512 channels, 4608 taps): the batch-folded GEMM on the micro-kernel. Columns are
// the positions of all items in order (column n·P + p), cut into 48-column panels that may hold
// the end of one item and the start of the next. The panels of a round are built first (R·48
// floats each), then tasks of (block of output rows, panel) run the micro-kernel: the rows are
// split because there are only a few panels, and each task's weight rows stay in cache across
// its panels. Each output element is the micro-kernel's fixed FMA sequence over R.
void conv_forward_folded(const ConvGeometry& g, const float* x, const float* packed, const float* b, float* y) {
  constexpr int64_t kCols = detail::kPanelCols, kRows = detail::kBlockRows;
  const int64_t P = g.out_plane(), R = g.rows(), cols = g.N * P, panels = (cols + kCols - 1) / kCols;
  const PhasedInput<float> phased = phase_input(g, x);
  // Panels are built and consumed in rounds of at most 16 MiB of columns (large batches).
  const int64_t per_round = std::clamp<int64_t>((int64_t{4} << 20) / (R * kCols), 1, panels);
  std::vector<float> col(static_cast<size_t>(per_round * R * kCols));
  const int64_t row_blocks = (g.O + kRows - 1) / kRows;
  for (int64_t first = 0; first < panels; first += per_round) {
    const int64_t count = std::min(per_round, panels - first);
    parallel_for(count, detail::grain_for(R * kCols), [&](int64_t p0, int64_t p1) {
      for (int64_t p = first + p0; p < first + p1; ++p) {
        folded_panel(g, x, phased, p, col.data() + (p - first) * R * kCols);
      }
    });
    const int64_t parts = std::min(row_blocks, (16 + count - 1) / count);  // >= 16 tasks: even over 2-4 threads
    parallel_for(parts * count, detail::grain_for(g.O * R * kCols / parts), [&](int64_t t0, int64_t t1) {
      std::vector<float> tile(static_cast<size_t>(g.O * kCols));
      for (int64_t t = t0; t < t1; ++t) {
        const int64_t part = t / count, p = first + t % count;
        const int64_t o0 = part * row_blocks / parts * kRows;
        const int64_t o1 = std::min(g.O, (part + 1) * row_blocks / parts * kRows);
        const int64_t c0 = p * kCols, c1 = std::min(cols, c0 + kCols);
        // A last panel of at most 32 columns (a 4 × 8 stage of 4 items: 128 = 2·48 + 32) runs the
        // 8 × 32 tile, the same FMA sequence per output with a third fewer FMAs than 48 columns.
        (c1 - c0 <= 2 * kCols / 3 ? detail::gemm_panel_narrow : detail::gemm_panel)(
            packed + o0 * R, o1 - o0, R, col.data() + (p - first) * R * kCols, c1 - c0, b ? b + o0 : nullptr,
            tile.data(), kCols, kCols);
        for (int64_t c = c0; c < c1;) {
          const int64_t n = c / P, q = c % P, cnt = std::min(P - q, c1 - c);
          for (int64_t o = o0; o < o1; ++o)
            std::copy_n(tile.data() + (o - o0) * kCols + (c - c0), cnt, y + (n * g.O + o) * P + q);
          c += cnt;
        }
      }
    });
  }
}

bool unit_stride(const ConvGeometry& g) { return g.stride[0] == 1 && g.stride[1] == 1 && g.stride[2] == 1; }

// Float on the micro-kernel, fewer than kMinDirectPositions positions per image (a ResNet's 4 × 8
// stage: 32 positions, 4608 taps): dW[O][R] = dY[O][N·P] · colᵀ[N·P][R], with the positions of all
// items as the GEMM's inner dimension. dY is gathered and packed like weights; im2col's panels (as
// the folded forward builds them) are transposed into colᵀ, whose 48-tap column blocks the
// micro-kernel streams (ldb = R) straight into dW (ldc = R). Each dW element is one fixed FMA
// sequence over the N·P positions, so the bits do not depend on threads. Returns false (nothing
// written) when colᵀ would pass 64 MiB.
bool conv_backward_weight_folded(const ConvGeometry& g, const float* x, const float* dy, float* dw) {
  constexpr int64_t kCols = detail::kPanelCols, kRows = detail::kBlockRows;
  const int64_t P = g.out_plane(), R = g.rows(), NP = g.N * P, panels = (NP + kCols - 1) / kCols;
  if (NP * R > (int64_t{16} << 20)) return false;
  const detail::CachedFloats col_t = detail::cached_floats(NP * R + kCols);  // + a panel row's overrun
  const PhasedInput<float> phased = phase_input(g, x);
  parallel_for(panels, detail::grain_for(R * kCols), [&](int64_t p0, int64_t p1) {
    std::vector<float> panel(static_cast<size_t>(R * kCols));
    for (int64_t p = p0; p < p1; ++p) {
      const int64_t c1 = std::min(NP, (p + 1) * kCols);
      folded_panel(g, x, phased, p, panel.data());
      float* dst = col_t.get() + p * kCols * R;  // colᵀ rows p·48 .. c1 − 1
#if defined(__AVX512F__)
      detail::transpose_copy(panel.data(), kCols, R, c1 - p * kCols, dst, R);
#else
      for (int64_t r = 0; r < R; ++r)
        for (int64_t j = 0; j < c1 - p * kCols; ++j) dst[j * R + r] = panel[r * kCols + j];
#endif
    }
  });
  std::vector<float> a(static_cast<size_t>(g.O * NP));  // dY as [O][N·P]
  for (int64_t n = 0; n < g.N; ++n)
    for (int64_t o = 0; o < g.O; ++o) std::copy_n(dy + (n * g.O + o) * P, P, a.data() + o * NP + n * P);
  const detail::PackedRows packed = detail::pack_rows(a.data(), g.O, NP);
  // Tasks: (48-tap panel, 8-row block), rows fastest, so that one panel of colᵀ (N·P × 48 floats)
  // stays in cache across all row blocks.
  const int64_t row_blocks = (g.O + kRows - 1) / kRows, tap_panels = (R + kCols - 1) / kCols;
  parallel_for(tap_panels * row_blocks, detail::grain_for(kRows * NP * kCols), [&](int64_t t0, int64_t t1) {
    for (int64_t t = t0; t < t1; ++t) {
      const int64_t o0 = t % row_blocks * kRows, r0 = t / row_blocks * kCols;
      detail::gemm_panel(packed.data() + o0 * NP, std::min(kRows, g.O - o0), NP, col_t.get() + r0,
                              std::min(kCols, R - r0), nullptr, dw + o0 * R + r0, R, R);
    }
  });
  return true;
}

// Whether a float convolution runs on the micro-kernel (AVX-512): all but pointwise layers with
// few positions, which stay on Eigen's GEMM.
bool uses_kernels(const ConvGeometry& g) {
  return detail::gemm_kernel_available() && (g.out_plane() >= kMinDirectPositions || !is_pointwise(g));
}

// Winograd F(2, 3) (conv_winograd.h): on the implicit GEMM's windows for large rows and volumes,
// else on gathered row pairs for 2-D convolutions with 3 undilated taps along the rows.
bool uses_winograd_windows(const ConvGeometry& g) {
  return g.out_plane() >= kMinDirectPositions && detail::direct_winograd_supported(g);
}
bool uses_winograd_rows(const ConvGeometry& g) { return !uses_winograd_windows(g) && detail::winograd_rows_supported(g); }

// The micro-kernel forward passes (uses_kernels(g)) on weights packed by pack_rows. `keep`
// (optional) receives the implicit GEMM's padded copy of x, for the weight gradient.
void conv_forward_kernels(const ConvGeometry& g, const float* x, const float* packed, const float* b, float* y,
                          detail::KeptInput* keep = nullptr) {
  if (g.out_plane() < kMinDirectPositions) return conv_forward_folded(g, x, packed, b, y);
  if (unit_stride(g)) return detail::direct_forward(g, x, packed, b, y, keep);
  if (detail::direct_strided_supported(g)) return detail::direct_forward_strided(g, x, packed, b, y);
  conv_forward_panels(g, x, packed, b, y);
}

// y[n] = W · im2col(x[n]) + b, one GEMM per (batch item, spatial tile).
template <class T>
void conv_forward(const ConvGeometry& g, const T* x, const T* w, const T* b, T* y, detail::KeptInput* keep = nullptr) {
  if constexpr (std::is_same_v<T, float>) {
    if (uses_kernels(g)) {
      if (uses_winograd_windows(g)) return detail::direct_forward_winograd(g, x, w, b, y, keep);
      if (uses_winograd_rows(g)) return detail::winograd_rows_forward(g, x, w, b, y);
      return conv_forward_kernels(g, x, detail::pack_rows(w, g.O, g.rows()).data(), b, y, keep);
    }
  }
  const int64_t P = g.out_plane(), R = g.rows();
  const ColumnBlocks cb = column_blocks<T>(g);
  const bool pointwise = is_pointwise(g);
  const PhasedInput<T> phased = phase_input(g, x);
  parallel_for(cb.count, detail::grain_for(g.O * R * cb.tile), [&](int64_t b0, int64_t b1) {
    std::vector<T> col, out;
    for (int64_t bi = b0; bi < b1; ++bi) {
      const ColumnBlocks::Block blk = cb.at(bi);
      const int64_t cols = blk.cols();
      const bool single = blk.n1 - blk.n0 == 1;
      const T* B = x + blk.n0 * g.C * g.in_plane() + blk.p0;
      int64_t ldb = P;
      if (!(pointwise && single)) {
        col.resize(static_cast<size_t>(R * cols));
        im2col_block(g, blk, x, phased, col.data());
        B = col.data();
        ldb = cols;
      }
      T* C = y + blk.n0 * g.O * P + blk.p0;
      int64_t ldc = P;
      if (!single) {
        out.resize(static_cast<size_t>(g.O * cols));
        C = out.data();
        ldc = cols;
      }
      sl::detail::gemm<T>(false, false, g.O, cols, R, T(1), w, R, B, ldb, T(0), C, ldc);
      for (int64_t n = blk.n0; n < blk.n1; ++n)
        for (int64_t o = 0; o < g.O; ++o) {
          T* dst = y + (n * g.O + o) * P + blk.p0;
          const T bias = b ? b[o] : T(0);
          if (single) {
            if (b) for (int64_t i = 0; i < blk.cnt; ++i) dst[i] += bias;
          } else {
            const T* src = out.data() + o * cols + (n - blk.n0) * blk.cnt;
            for (int64_t i = 0; i < blk.cnt; ++i) dst[i] = src[i] + bias;
          }
        }
    }
  });
}

// dW = Σ dy[n] · im2col(x[n])ᵀ. The (batch item, tile) tasks are cut into a
// number of groups fixed by the shapes; each group sums its tasks in order into its own
// partial, and the partials are added in group order: the bits never depend on threads.
template <class T>
void conv_backward_weight(const ConvGeometry& g, const T* x, const T* dy, T* dw,
                          const detail::PaddedInput* kept = nullptr) {
  if constexpr (std::is_same_v<T, float>) {
    if (detail::gemm_kernel_available() && unit_stride(g) && g.out_plane() >= kMinDirectPositions)
      return detail::direct_backward_weight(g, x, dy, dw, kept);
    if (detail::gemm_kernel_available() && detail::direct_strided_supported(g) && g.out_plane() >= kMinDirectPositions)
      return detail::direct_backward_weight_strided(g, x, dy, dw);
    if (detail::gemm_kernel_available() && g.out_plane() < kMinDirectPositions && conv_backward_weight_folded(g, x, dy, dw))
      return;
  }
  const int64_t P = g.out_plane(), R = g.rows(), per = g.O * R;
  const ColumnBlocks cb = column_blocks<T>(g);
  const int64_t tasks = cb.count;
  const int64_t memory_cap = std::max<int64_t>(1, (int64_t{16} << 20) / (per * static_cast<int64_t>(sizeof(T))));
  const int64_t groups = std::min({tasks, int64_t{8}, memory_cap});
  // One group (deep layers: all items in one block) sums straight into dw, which its first task
  // overwrites: no partial to zero and copy (megabytes here). The sums are the same.
  std::vector<T> partial(groups > 1 ? static_cast<size_t>(groups * per) : 0, T(0));
  T* const sums = groups > 1 ? partial.data() : dw;
  const bool pointwise = is_pointwise(g);
  const PhasedInput<T> phased = phase_input(g, x);
  const bool use_kernel = detail::gemm_kernel_available() && P >= kMinDirectPositions;
  parallel_for(groups, detail::grain_for(per * cb.tile * tasks / groups), [&](int64_t g0, int64_t g1) {
    std::vector<T> col, dyb;
    std::vector<int64_t> row_offset;
    for (int64_t grp = g0; grp < g1; ++grp)
      for (int64_t t = grp * tasks / groups; t < (grp + 1) * tasks / groups; ++t) {
        const ColumnBlocks::Block blk = cb.at(t);
        const int64_t cols = blk.cols();
        const bool single = blk.n1 - blk.n0 == 1;
        const T* B = x + blk.n0 * g.C * g.in_plane() + blk.p0;
        const T* A = dy + blk.n0 * g.O * P + blk.p0;
        int64_t ldb = P, lda = P;
        if (!(pointwise && single)) {
          col.resize(static_cast<size_t>(R * cols));
          im2col_block(g, blk, x, phased, col.data());
          B = col.data();
          ldb = cols;
        }
        if (!single) {
          dyb.resize(static_cast<size_t>(g.O * cols));
          gather_block(blk, dy, g.O, P, dyb.data());
          A = dyb.data();
          lda = cols;
        }
        const bool first = groups == 1 && t == 0;
        if constexpr (std::is_same_v<T, float>) {
          if (use_kernel) {  // dy rows · col rows, the weight-gradient micro-kernel of conv_gemm.h
            row_offset.resize(static_cast<size_t>(R));
            for (int64_t k = 0; k < R; ++k) row_offset[k] = k * ldb;
            if (first) std::fill(dw, dw + per, 0.0f);
            // A single group (all items in one block) splits its 8-row blocks over the threads;
            // each block's sums are the same whichever call computes them.
            const int64_t row_blocks = (g.O + detail::kBlockRows - 1) / detail::kBlockRows;
            const int64_t parts = groups == 1 ? std::min<int64_t>(row_blocks, 16) : 1;
            parallel_for(parts, 1, [&](int64_t q0, int64_t q1) {
              for (int64_t part = q0; part < q1; ++part) {
                const int64_t o0 = part * row_blocks / parts * detail::kBlockRows;
                const int64_t o1 = std::min(g.O, (part + 1) * row_blocks / parts * detail::kBlockRows);
                detail::conv_weight_grad_window(A + o0 * lda, lda, o1 - o0, B, row_offset.data(), R, cols,
                                                sums + grp * per + o0 * R);
              }
            });
            continue;
          }
        }
        sl::detail::gemm<T>(false, true, g.O, R, cols, T(1), A, lda, B, ldb, first ? T(0) : T(1), sums + grp * per, R);
      }
  });
  if (groups > 1) detail::sum_groups(partial.data(), groups, per, dw);
}

// db[o] = Σ dy[:, o] in a fixed order per channel (independent of threads).
template <class T>
void conv_bias_grad(const ConvGeometry& g, const T* dy, T* db) {
  const int64_t P = g.out_plane();
  parallel_for(g.O, detail::grain_for(g.N * P), [&](int64_t o0, int64_t o1) {
    for (int64_t o = o0; o < o1; ++o) {
      double acc = 0;
      for (int64_t n = 0; n < g.N; ++n) {
        const T* row = dy + (n * g.O + o) * P;
        // 16 interleaved partial sums (a fixed order the compiler can vectorise), then in double.
        T lanes[16] = {};
        int64_t i = 0;
        for (; i + 16 <= P; i += 16)
          for (int j = 0; j < 16; ++j) lanes[j] += row[i + j];
        for (int j = 0; i < P; ++i, ++j) lanes[j] += row[i];
        for (T v : lanes) acc += v;
      }
      db[o] = static_cast<T>(acc);
    }
  });
}

// dx = col2im(Wᵀ · dy). With stride 1 (and padding no larger than the dilated kernel) this is
// the forward convolution of dy with the flipped, transposed kernel, which has no scatter and
// tiles over (batch, space) like the forward pass. Otherwise each batch item scatters its
// column gradients sequentially (one writer per item keeps it race-free and deterministic).
bool input_grad_is_conv(const ConvGeometry& g) {
  bool as_conv = true;
  for (int a = 0; a < 3; ++a) as_conv = as_conv && g.stride[a] == 1 && g.dil[a] * (g.k[a] - 1) - g.pad[a] >= 0;
  return as_conv;
}

// wt[c][o][flipped tap] = w[o][c][tap], one input channel per task (deep layers have megabytes
// of weights).
template <class T>
std::vector<T> flipped_transposed(const ConvGeometry& g, const T* w) {
  const int64_t taps = g.taps();
  std::vector<T> wt(static_cast<size_t>(g.O * g.rows()));
  parallel_for(g.C, detail::grain_for(g.O * taps), [&](int64_t c0, int64_t c1) {
    for (int64_t c = c0; c < c1; ++c)
      for (int64_t o = 0; o < g.O; ++o)
        for (int64_t k = 0; k < taps; ++k) wt[(c * g.O + o) * taps + (taps - 1 - k)] = w[(o * g.C + c) * taps + k];
  });
  return wt;
}

// Float, strided, >= kMinDirectPositions positions: dcol = Wᵀ · dy one 48-column panel at a time
// on the micro-kernel (dy rows are read in place as its B windows), then col2im of the panel, into
// a phased copy of the item's gradient (contiguous adds, see col2im_tile_phased) whose phases are
// merged into dx at the end when the kernel spans the stride. One batch item per task keeps the
// scatter race-free; writes all of dx.
void input_grad_panels(const ConvGeometry& g, const float* w, const float* dy, float* dx) {
  const int64_t P = g.out_plane(), R = g.rows();
  const detail::PackedRows packed = detail::pack_rows_transposed(w, g.O, R);  // Wᵀ: [R, O]
  const detail::PhasedRows ph = detail::phased_rows(g);
  const int64_t rows = g.C * g.in[0] * g.in[1];  // input rows per item
  // Phased when the kernel covers every phase of a row; otherwise (a strided 1×1) most of the
  // phased copy would be zeros to clear and merge, and dx is scattered into directly.
  const bool phased = ph.stride > 1 && g.k[2] >= ph.stride;
  std::vector<int64_t> in_place(static_cast<size_t>(g.O)), padded(static_cast<size_t>(g.O));
  for (int64_t k = 0; k < g.O; ++k) in_place[k] = k * P, padded[k] = k * detail::kPanelCols;
  parallel_for(g.N, detail::grain_for(R * P * g.O), [&](int64_t n0, int64_t n1) {
    std::vector<float> tile(static_cast<size_t>((R + detail::kBlockRows) * detail::kPanelCols));
    std::vector<float> last(static_cast<size_t>(g.O * detail::kPanelCols), 0.0f);
    std::vector<float> dxp(phased ? static_cast<size_t>(rows * ph.row_pitch()) : 0);
    for (int64_t n = n0; n < n1; ++n) {
      float* const dxn = dx + n * g.C * g.in_plane();
      if (phased) {
        std::fill(dxp.begin(), dxp.end(), 0.0f);
      } else {
        std::fill(dxn, dxn + g.C * g.in_plane(), 0.0f);
      }
      for (int64_t q = 0; q < P; q += detail::kPanelCols) {
        const int64_t cnt = std::min(detail::kPanelCols, P - q);
        const float* base = dy + n * g.O * P + q;
        const int64_t* offsets = in_place.data();
        if (cnt < detail::kPanelCols) {  // the windows of a short last panel would run past dy
          for (int64_t k = 0; k < g.O; ++k) std::copy(base + k * P, base + k * P + cnt, last.data() + k * detail::kPanelCols);
          base = last.data();
          offsets = padded.data();
        }
        detail::conv_gemm_window(packed.data(), R, g.O, base, offsets, tile.data());
        if (phased) {
          detail::col2im_tile_phased(tile.data(), g, ph, q, cnt, dxp.data(), detail::kPanelCols);
        } else {
          detail::col2im_tile(tile.data(), g, q, cnt, dxn, detail::kPanelCols);
        }
      }
      if (phased) detail::merge_phases(dxp.data(), rows, g.in[2], ph, dxn);
    }
  });
}

template <class T>
void conv_backward_input(const ConvGeometry& g, const T* w, const T* dy, T* dx) {
  const int64_t R = g.rows();
  if (input_grad_is_conv(g)) {
    const ConvGeometry t = input_grad_geometry(g);
    if constexpr (std::is_same_v<T, float>) {
      if (uses_kernels(t) && uses_winograd_windows(t)) return detail::direct_backward_input(g, w, dy, dx);
      if (uses_kernels(t) && uses_winograd_rows(t))
        return detail::winograd_rows_forward(t, dy, w, nullptr, dx, true);
      if (uses_kernels(t))
        return conv_forward_kernels(t, dy, detail::pack_weights_flipped(w, g.O, g.C, g.taps()).data(), nullptr, dx);
    }
    conv_forward<T>(t, dy, flipped_transposed(g, w).data(), nullptr, dx);
    return;
  }
  // Column gradients are scattered by col2im, so all blocks of one batch item go to one task.
  const int64_t P = g.out_plane();
  const ColumnBlocks cb = column_blocks<T>(g);
  if constexpr (std::is_same_v<T, float>) {
    if (detail::gemm_kernel_available() && P >= kMinDirectPositions)
      return input_grad_panels(g, w, dy, dx);  // every block holds a single item here
  }
  std::fill(dx, dx + g.N * g.C * g.in_plane(), T(0));
  const int64_t owners = cb.items_per_block == 1 ? g.N : cb.count;
  const int64_t per_owner = cb.items_per_block == 1 ? cb.tiles_per_item : 1;
  parallel_for(owners, detail::grain_for(R * P * g.O * cb.items_per_block), [&](int64_t w0, int64_t w1) {
    std::vector<T> col, dyb;
    for (int64_t owner = w0; owner < w1; ++owner)
      for (int64_t s = 0; s < per_owner; ++s) {
        const ColumnBlocks::Block blk = cb.at(owner * per_owner + s);
        const int64_t cols = blk.cols();
        const T* A = dy + blk.n0 * g.O * P + blk.p0;
        int64_t lda = P;
        if (blk.n1 - blk.n0 > 1) {
          dyb.resize(static_cast<size_t>(g.O * cols));
          gather_block(blk, dy, g.O, P, dyb.data());
          A = dyb.data();
          lda = cols;
        }
        col.resize(static_cast<size_t>(R * cols));
        sl::detail::gemm<T>(true, false, R, cols, g.O, T(1), w, R, A, lda, T(0), col.data(), cols);
        // One (item, channel) plane per call: each dx element still gets its additions in tap
        // order. When all items share one block (deep layers) this runs on all threads.
        ConvGeometry one = g;
        one.C = 1;
        const int64_t taps = g.taps();
        parallel_for((blk.n1 - blk.n0) * g.C, detail::grain_for(taps * blk.cnt), [&](int64_t i0, int64_t i1) {
          for (int64_t i = i0; i < i1; ++i) {
            const int64_t n = blk.n0 + i / g.C, c = i % g.C;
            detail::col2im_tile(col.data() + c * taps * cols + (n - blk.n0) * blk.cnt, one, blk.p0, blk.cnt,
                                dx + (n * g.C + c) * g.in_plane(), cols);
          }
        });
      }
  });
}

// Float, stride 1, both gradients of a "same" convolution: one padded copy of dy serves both.
// Not where the input gradient runs as Winograd on gathered row pairs (faster than sharing the copy).
bool conv_backward_fused(const ConvGeometry& g, const float* x, const float* w, const float* dy, float* dx, float* dw,
                         const detail::PaddedInput* kept) {
  return detail::gemm_kernel_available() && g.out_plane() >= kMinDirectPositions &&
         !(input_grad_is_conv(g) && uses_winograd_rows(detail::input_grad_geometry(g))) &&
         detail::direct_backward_fused(g, x, w, dy, dx, dw, kept);
}

bool conv_backward_fused(const ConvGeometry&, const double*, const double*, const double*, double*, double*,
                         const detail::PaddedInput*) {
  return false;  // float64 (gradient checks) keeps the reference path
}

template <size_t Dm>
Tensor conv_nd(const char* op, const Tensor& x_in, const Tensor& w_in, const Tensor& b_in,
               const std::array<int64_t, Dm>& stride, const std::array<int64_t, Dm>& padding,
               const std::array<int64_t, Dm>& dilation) {
  SL_CHECK(x_in.defined() && w_in.defined(), op, ": input and weight must be defined");
  SL_CHECK(x_in.dim() == Dm + 2, op, ": input must be ", Dm + 2, "-d [N, C, ...], got ", x_in.describe());
  SL_CHECK(w_in.dim() == Dm + 2, op, ": weight must be ", Dm + 2, "-d [O, C, ...], got ", w_in.describe());
  SL_CHECK(x_in.size(1) == w_in.size(1), op, ": input ", shape_str(x_in.shape()), " has ", x_in.size(1),
           " channels, weight ", shape_str(w_in.shape()), " expects ", w_in.size(1));
  SL_CHECK(x_in.dtype() == w_in.dtype(), op, ": dtypes differ: input ", x_in.describe(), ", weight ",
           w_in.describe());
  if (b_in.defined()) {
    SL_CHECK(b_in.dim() == 1 && b_in.size(0) == w_in.size(0), op, ": bias ", shape_str(b_in.shape()),
             " must be [", w_in.size(0), "] for weight ", shape_str(w_in.shape()));
    SL_CHECK(b_in.dtype() == x_in.dtype(), op, ": dtypes differ: input ", x_in.describe(), ", bias ",
             b_in.describe());
  }
  ConvGeometry g;
  g.N = x_in.size(0);
  g.C = x_in.size(1);
  g.O = w_in.size(0);
  for (int a = 0; a < 3; ++a) g.in[a] = g.k[a] = g.stride[a] = g.dil[a] = 1, g.pad[a] = 0;
  for (size_t a = 0; a < Dm; ++a) {
    const size_t s = 3 - Dm + a;
    SL_CHECK(stride[a] >= 1 && dilation[a] >= 1 && padding[a] >= 0, op, ": stride and dilation must be >= 1 and ",
             "padding >= 0, got stride ", stride[a], ", padding ", padding[a], ", dilation ", dilation[a]);
    g.in[s] = x_in.size(2 + a);
    g.k[s] = w_in.size(2 + a);
    g.stride[s] = stride[a];
    g.pad[s] = padding[a];
    g.dil[s] = dilation[a];
  }
  Shape out_shape = {g.N, g.O};
  for (int a = 0; a < 3; ++a) {
    const int64_t span = g.in[a] + 2 * g.pad[a] - g.dil[a] * (g.k[a] - 1) - 1;
    SL_CHECK(g.k[a] >= 1 && span >= 0, op, ": kernel ", shape_str(w_in.shape()), " (dilated) does not fit input ",
             shape_str(x_in.shape()), " with the given padding");
    g.out[a] = span / g.stride[a] + 1;
    if (a >= static_cast<int>(3 - Dm)) out_shape.push_back(g.out[a]);
  }
  const Tensor x = x_in.detach().contiguous(), w = w_in.detach().contiguous();
  const Tensor b = b_in.defined() ? b_in.detach().contiguous() : Tensor();
  Tensor y = Tensor::empty(out_shape, x.dtype());
  // When the weight will need a gradient, the forward's padded copy of x (if it makes one) is
  // kept for it: conv_implicit_gemm.h, "Keeping the forward's copy".
  detail::KeptInput kept;
  const bool recording = needs_grad({x_in, w_in, b_in});
  const bool keep = recording && w_in.requires_grad();
  if (y.numel() > 0)
    SL_DISPATCH_FLOAT(x.dtype(), op, [&] {
      using T = scalar_t;
      conv_forward<T>(g, x.data<T>(), w.data<T>(), b.defined() ? b.data<T>() : nullptr, y.data<T>(),
                      keep ? &kept : nullptr);
    });
  if (recording) {
    const bool gx = x_in.requires_grad(), gw = w_in.requires_grad(), gb = b_in.defined() && b_in.requires_grad();
    record(op, {x_in, w_in, b_in}, {y}, [=](const TensorList& grads) {
      const Tensor dy = grads[0].contiguous();
      TensorList r(3);
      // Every kernel below overwrites its whole gradient: no zero fill (a serial pass over dx).
      auto make = [&](bool need, const Tensor& like) {
        return need ? (dy.numel() == 0 ? Tensor::zeros(like.shape(), like.dtype()) : Tensor::empty(like.shape(), like.dtype()))
                    : Tensor();
      };
      r[0] = make(gx, x);
      r[1] = make(gw, w);
      r[2] = make(gb, b);
      if (dy.numel() == 0) return r;
      SL_DISPATCH_FLOAT(x.dtype(), op, [&] {
        using T = scalar_t;
        bool fused = false;
        if (gx && gw)
          fused = conv_backward_fused(g, x.data<T>(), w.data<T>(), dy.data<T>(), r[0].data<T>(), r[1].data<T>(),
                                      kept.get());
        if (gx && !fused) conv_backward_input<T>(g, w.data<T>(), dy.data<T>(), r[0].data<T>());
        if (gw && !fused) conv_backward_weight<T>(g, x.data<T>(), dy.data<T>(), r[1].data<T>(), kept.get());
        if (gb) conv_bias_grad<T>(g, dy.data<T>(), r[2].data<T>());
      });
      return r;
    });
  }
  return y;
}

}  // namespace

Tensor conv2d(const Tensor& x, const Tensor& w, const Tensor& bias, std::array<int64_t, 2> stride,
              std::array<int64_t, 2> padding, std::array<int64_t, 2> dilation) {
  return conv_nd<2>("conv2d", x, w, bias, stride, padding, dilation);
}

Tensor conv3d(const Tensor& x, const Tensor& w, const Tensor& bias, std::array<int64_t, 3> stride,
              std::array<int64_t, 3> padding, std::array<int64_t, 3> dilation) {
  return conv_nd<3>("conv3d", x, w, bias, stride, padding, dilation);
}

}  // namespace sl::nn
