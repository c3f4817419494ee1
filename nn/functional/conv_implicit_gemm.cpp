#include "nn/functional/conv_implicit_gemm.h"

#include <algorithm>
#include <array>
#include <cstdlib>
#include <memory>
#include <vector>

#if defined(__AVX512F__)
#include <immintrin.h>
#endif

#include "autodiff/buffer_cache.h"
#include "nn/functional/conv_microkernel.h"
#include "nn/functional/conv_padding.h"
#include "nn/functional/conv_tuning.h"
#include "nn/functional/conv_winograd.h"
#include "nn/functional/group_sums.h"
#include "autodiff/transpose16.h"
#include "nn/functional/work_grain.h"
#include "util/error.h"
#include "util/parallel.h"

namespace sl::nn::detail {
namespace {

// Per-thread scratch, reused across tasks and calls (contents unspecified). The forwards' task
// bodies run once per task (grain 1), and a fresh zeroed vector per task (147 KiB of tiles for a
// block of 16 planes) was an mmap, page faults and a memset each time: 7% of a 1×16×64×64×16
// forward (perf, 1 thread).
float* thread_scratch(int slot, int64_t floats) {
  thread_local std::vector<float> buffers[2];
  std::vector<float>& b = buffers[slot];
  if (b.size() < static_cast<size_t>(floats)) b.resize(static_cast<size_t>(floats));
  return b.data();
}

// Copies positions [q0, q1) of the padded pitch from the tiles into y: the runs whose column is
// below out[2] (the others are dropped positions), plus the bias. tiles holds, for each of the nz
// outer planes of a block, [O][cols] values of positions q0.. at tiles + j·tile_floats. When
// block > 1 (ys[0] == 1: the planes of the block are contiguous in y) they are stored together.
struct OutputRuns {
  Axes out, ys;
  int64_t Wp = 0, P = 0, O = 0, block = 1, cols = kPanelCols, tile_floats = 0;
};

void store_runs(const OutputRuns& r, const float* tiles, int64_t nz, int64_t q0, int64_t q1, const float* b,
                float* yz) {
  for (int64_t q = q0; q < q1;) {
    const int64_t row = q / r.Wp, col = q % r.Wp, run_end = std::min(q1, row * r.Wp + r.out[2]);
    if (col < r.out[2]) {
      const int64_t len = run_end - q;
      for (int64_t o = 0; o < r.O; ++o) {
        const float bias = b ? b[o] : 0.0f;
        const float* src = tiles + o * r.cols + (q - q0);
        float* dst = yz + o * r.P + row * r.ys[1] + col * r.ys[2];
        if (r.block > 1) {
          int64_t i = 0;
#if defined(__AVX512F__)
          // 16 positions × up to 16 planes per step through a register transpose: one masked
          // vector store per position instead of one scalar per element (the scalar loop was 6%
          // of a 1×16×64×64×16 forward, perf, 1 thread).
          const __m512 bv = _mm512_set1_ps(bias);
          const __mmask16 planes = static_cast<__mmask16>((1u << nz) - 1u);
          for (; i < len; i += 16) {
            const int64_t cnt = std::min<int64_t>(16, len - i);
            const __mmask16 m = static_cast<__mmask16>((1u << cnt) - 1u);
            __m512 v[16];
            for (int64_t j = 0; j < 16; ++j)
              v[j] = j < nz ? _mm512_add_ps(_mm512_maskz_loadu_ps(m, src + j * r.tile_floats + i), bv)
                            : _mm512_setzero_ps();
            transpose16(v);
            for (int64_t k = 0; k < cnt; ++k) _mm512_mask_storeu_ps(dst + (i + k) * r.ys[2], planes, v[k]);
          }
#endif
          for (; i < len; ++i)
            for (int64_t j = 0; j < nz; ++j) dst[i * r.ys[2] + j] = src[j * r.tile_floats + i] + bias;
        } else if (r.ys[2] == 1) {
          int64_t i = 0;
#if defined(__AVX512F__)
          // Runs are a few dozen floats: masked vectors rather than a scalar tail of up to 15.
          const __m512 bv = _mm512_set1_ps(bias);
          for (; i + 16 <= len; i += 16) _mm512_storeu_ps(dst + i, _mm512_add_ps(_mm512_loadu_ps(src + i), bv));
          if (i < len) {
            const __mmask16 m = static_cast<__mmask16>((1u << (len - i)) - 1u);
            _mm512_mask_storeu_ps(dst + i, m, _mm512_add_ps(_mm512_maskz_loadu_ps(m, src + i), bv));
          }
          i = len;
#endif
          for (; i < len; ++i) dst[i] = src[i] + bias;
        } else {
          for (int64_t i = 0; i < len; ++i) dst[i * r.ys[2]] = src[i] + bias;
        }
      }
    }
    q = (row + 1) * r.Wp;
  }
}

// The task split shared by both forwards: tasks are (batch item, chunk of up to 8 steps of `cols`
// positions, block of outer planes), blocks fastest. Chunks shrink until there are at least
// kMinTasks tasks: tasks are split statically, so 11 equal tasks (a 64×64×16 volume in 8-panel
// chunks) leave one of two threads idle for a task's length (9% of the call); the tiles and their
// bits do not change. When the outer storage axis is y's innermost one (a reordered copy), a block
// of up to 16 planes is computed first and then stored with the planes contiguous, so y is written
// in whole cache lines rather than one float per line.
struct ForwardTasks {
  OutputRuns runs;
  int64_t span = 0, chunk = 0, chunks = 0, blocks = 0, count = 0;
};

ForwardTasks forward_tasks(const ConvGeometry& g, const Order& order, const Padded& xp, int64_t cols) {
  ForwardTasks t;
  OutputRuns& r = t.runs;
  r.out = permute(g.out, order);
  r.ys = permute(out_strides(g), order);
  r.Wp = xp.ext[2];
  r.P = g.out_plane();
  r.O = g.O;
  r.cols = cols;
  r.tile_floats = (g.O + kBlockRows) * cols;
  r.block = r.ys[0] == 1 && r.out[0] > 1 ? std::clamp<int64_t>(65536 / r.tile_floats, 1, 16) : 1;
  t.span = (r.out[1] - 1) * r.Wp + r.out[2];  // one output plane on the padded pitch
  t.blocks = (r.out[0] + r.block - 1) / r.block;
  constexpr int64_t kMinTasks = 32;
  const int64_t steps = (t.span + cols - 1) / cols;
  t.chunk = std::clamp<int64_t>(steps * g.N * t.blocks / kMinTasks, 1, 8) * cols;
  t.chunks = (t.span + t.chunk - 1) / t.chunk;
  t.count = g.N * t.chunks * t.blocks;
  return t;
}

// Row by row: the panels of each output row (48 positions each, the last one narrower) written
// straight into y with the bias, for outputs whose innermost storage axis is y's contiguous one.
// Against the panels along the padded pitch, it computes no dropped positions and skips
// store_runs' copy, but a row's last panel may be a narrow tile. Each output is the same FMA
// sequence either way, so the choice (forward_padded) does not change a bit.

// Share of the window kernel's time that store_runs adds on the panels along the pitch: 9% on
// the ResNet stem (perf, 1 thread, AMD EPYC family 25: 2.2% of samples against 24.4%).
constexpr double kStoreShare = 0.09;

// Whether to walk the outputs by rows. pitch: the padded copy's row pitch (xp.ext[2]).
bool by_rows(const ConvGeometry& g, const Order& order, int64_t pitch, ForwardPanels how) {
  const Axes out = permute(g.out, order), ys = permute(out_strides(g), order);
  if (ys[2] != 1 || how == ForwardPanels::kPitch) return false;
  if (how == ForwardPanels::kRows) return true;
  const int64_t full = out[2] / kPanelCols, rem = out[2] % kPanelCols;  // per row: full panels, then rem
  const int64_t span = (out[1] - 1) * pitch + out[2];
  const double rows_cost = static_cast<double>(out[1]) * (full + (rem ? conv_window_cost(rem) : 0.0));
  const double pitch_cost = static_cast<double>((span + kPanelCols - 1) / kPanelCols) * (1.0 + kStoreShare);
  return rows_cost < pitch_cost;
}

void forward_rows(const ConvGeometry& g, const Order& order, const Padded& xp, const std::vector<int64_t>& taps,
                  const float* packed, const float* b, float* y) {
  const int64_t R = g.rows(), Hp = xp.ext[1], Wp = xp.ext[2], P = g.out_plane();
  const Axes out = permute(g.out, order), ys = permute(out_strides(g), order);
  const int64_t rows = out[0] * out[1], cols = out[2];
  parallel_for(g.N * rows, grain_for(g.O * R * cols), [&](int64_t t0, int64_t t1) {
    for (int64_t t = t0; t < t1; ++t) {
      const int64_t n = t / rows, z = t % rows / out[1], row = t % out[1];
      const float* xr = xp.data.get() + n * g.C * xp.volume + z * Hp * Wp + row * Wp;
      float* yr = y + n * g.O * P + z * ys[0] + row * ys[1];
      for (int64_t j = 0; j < cols; j += kPanelCols)
        conv_gemm_window_store(packed, g.O, R, xr + j, taps.data(), std::min(kPanelCols, cols - j), b, yr + j, P,
                               kPanelCols);
    }
  });
}

// y = conv(x) + b from the padded copy, one 48-position panel per micro-kernel call: by rows
// (forward_rows) when that is estimated cheaper, else along the padded pitch.
void forward_padded(const ConvGeometry& g, const Order& order, const Padded& xp, const std::vector<int64_t>& taps,
                    const float* packed, const float* b, float* y, ForwardPanels how = ForwardPanels::kChoose) {
  if (by_rows(g, order, xp.ext[2], how)) return forward_rows(g, order, xp, taps, packed, b, y);
  const int64_t R = g.rows(), Hp = xp.ext[1], Wp = xp.ext[2];
  const ForwardTasks ft = forward_tasks(g, order, xp, kPanelCols);
  const OutputRuns& r = ft.runs;
  parallel_for(ft.count, grain_for(g.O * R * ft.chunk * r.block), [&](int64_t t0, int64_t t1) {
    float* const tiles = thread_scratch(0, r.block * r.tile_floats);
    for (int64_t t = t0; t < t1; ++t) {
      const int64_t z0 = t % ft.blocks * r.block, c0 = (t / ft.blocks) % ft.chunks * ft.chunk;
      const int64_t n = t / (ft.blocks * ft.chunks), nz = std::min(r.block, r.out[0] - z0);
      const float* xn = xp.data.get() + n * g.C * xp.volume;
      for (int64_t q0 = c0; q0 < std::min(ft.span, c0 + ft.chunk); q0 += kPanelCols) {
        for (int64_t j = 0; j < nz; ++j)
          conv_gemm_window(packed, g.O, R, xn + (z0 + j) * Hp * Wp + q0, taps.data(), tiles + j * r.tile_floats);
        store_runs(r, tiles, nz, q0, std::min(ft.span, q0 + kPanelCols), b, y + n * g.O * r.P + z0 * r.ys[0]);
      }
    }
  });
}

// y = conv(x) + b from the padded copy (even pitch) by Winograd F(2, 3): per step, four
// micro-kernel tiles of 48 pairs, combined into 96 outputs. w: [O][C][taps] (flipped: see
// winograd_weights), not packed.
void forward_winograd(const ConvGeometry& g, const Order& order, const Padded& xp, const float* w, const float* b,
                      float* y, bool flipped = false, const WinogradInput* pre = nullptr) {
  SL_CHECK(winograd_applies(g, order) && xp.ext[2] % 2 == 0, "conv: Winograd forward on an unsupported geometry");
  const WinogradWeights v = winograd_weights(g, order[2], w, flipped);
  WinogradInput own;
  if (!pre) own = winograd_input(xp, g.N, g.C);
  const WinogradInput& u = pre ? *pre : own;
  const std::vector<int64_t> taps = winograd_tap_offsets(g, order, xp);
  const int64_t R = g.rows() / 3, plane = xp.ext[1] * xp.ext[2] / 2, comp = (g.O + kBlockRows) * kPanelCols;
  constexpr int64_t kCols = 2 * kPanelCols;
  const ForwardTasks ft = forward_tasks(g, order, xp, kCols);
  const OutputRuns& r = ft.runs;
  parallel_for(ft.count, grain_for(2 * g.O * R * ft.chunk * r.block), [&](int64_t t0, int64_t t1) {
    float* const m = thread_scratch(1, 4 * comp);
    float* const tiles = thread_scratch(0, r.block * r.tile_floats);
    for (int64_t t = t0; t < t1; ++t) {
      const int64_t z0 = t % ft.blocks * r.block, c0 = (t / ft.blocks) % ft.chunks * ft.chunk;
      const int64_t n = t / (ft.blocks * ft.chunks), nz = std::min(r.block, r.out[0] - z0);
      const float* un = u.data.get() + n * 4 * g.C * u.half;
      for (int64_t q0 = c0; q0 < std::min(ft.span, c0 + ft.chunk); q0 += kCols) {
        for (int64_t j = 0; j < nz; ++j) {
          const float* base = un + (z0 + j) * plane + q0 / 2;
          for (int64_t i = 0; i < 4; ++i)
            conv_gemm_window(v.data(i), g.O, R, base + i * g.C * u.half, taps.data(), m + i * comp);
          float* tile = tiles + j * r.tile_floats;
          for (int64_t o = 0; o < g.O; ++o) {
            const float* m1 = m + o * kPanelCols;
            const float *m2 = m1 + comp, *m3 = m2 + comp, *m4 = m3 + comp;
            float* dst = tile + o * kCols;
            int64_t p0 = 0;
#if defined(__AVX512F__)
            const __m512i lo = _mm512_setr_epi32(0, 16, 1, 17, 2, 18, 3, 19, 4, 20, 5, 21, 6, 22, 7, 23);
            const __m512i hi = _mm512_add_epi32(lo, _mm512_set1_epi32(8));
            for (; p0 < kPanelCols; p0 += 16) {
              const __m512 a = _mm512_loadu_ps(m1 + p0), c = _mm512_loadu_ps(m2 + p0);
              const __m512 e = _mm512_loadu_ps(m3 + p0), f = _mm512_loadu_ps(m4 + p0);
              const __m512 y0 = _mm512_add_ps(_mm512_add_ps(a, c), e), y1 = _mm512_sub_ps(_mm512_sub_ps(c, e), f);
              _mm512_storeu_ps(dst + 2 * p0, _mm512_permutex2var_ps(y0, lo, y1));
              _mm512_storeu_ps(dst + 2 * p0 + 16, _mm512_permutex2var_ps(y0, hi, y1));
            }
#endif
            for (int64_t p = p0; p < kPanelCols; ++p) {
              dst[2 * p] = m1[p] + m2[p] + m3[p];
              dst[2 * p + 1] = m2[p] - m3[p] - m4[p];
            }
          }
        }
        store_runs(r, tiles, nz, q0, std::min(ft.span, q0 + kCols), b, y + n * g.O * r.P + z0 * r.ys[0]);
      }
    }
  });
}

// u (optional): the Winograd transform of padded_dy (pad_output_grad made it with the copy).
void input_grad_from(const ConvGeometry& g, const Order& order, const Padded& padded_dy, const float* w, float* dx,
                     const WinogradInput* u = nullptr) {
  const ConvGeometry t = input_grad_geometry(g);
  if (winograd_applies(t, order)) return forward_winograd(t, order, padded_dy, w, nullptr, dx, true, u);
  forward_padded(t, order, padded_dy, tap_offsets(t, order, padded_dy),
                 pack_weights_flipped(w, g.O, g.C, g.taps()).data(), nullptr, dx);
}

// How the weight gradients cut their work: each batch item's len_total positions into `chunks`
// chunks of equal length (a multiple of 16 positions, at most max_chunk; the last may be
// shorter), and items shorter than a chunk grouped `items_per_call` to a kernel call, with the
// calls holding equal numbers of items. The calls go to the threads in contiguous runs, so
// unequal calls idle a thread: ResNet-18's 32×64 stage was cut 2048 + 62 (max_chunk 2048), and
// its 16×32 stage's 4 items went 3 + 1 to two calls, one thread waiting through two items' work.
struct WeightGradSplit {
  int64_t chunk = 0, chunks = 0, tasks = 0, items_per_call = 0, calls = 0;
};

WeightGradSplit weight_grad_split(int64_t items, int64_t len_total, int64_t max_chunk) {
  WeightGradSplit s;
  s.chunks = (len_total + max_chunk - 1) / max_chunk;
  s.chunk = std::min(max_chunk, ((len_total + s.chunks - 1) / s.chunks + 15) / 16 * 16);
  s.tasks = items * s.chunks;
  const int64_t most = s.chunks == 1 ? std::max<int64_t>(1, max_chunk / len_total) : 1;
  const int64_t calls = (s.tasks + most - 1) / most;
  s.items_per_call = (s.tasks + calls - 1) / calls;
  s.calls = (s.tasks + s.items_per_call - 1) / s.items_per_call;
  return s;
}

#if defined(__AVX512F__)
// weight_grad (below) on the outer-product kernel (conv_weight_grad_outer): dy, on the padded
// pitch with zeros at the dropped positions (dy_base, dy_pitch floats per (n, o) plane), is
// transposed once to dyT[n][q][o] (o padded to whole vectors of 16), and the tasks accumulate
// dwT[tap][o] partials. Tasks: the same fixed groups of (item, chunk) calls as the window kernel,
// each group split further by blocks of taps (not of channels: every task then reads whole
// vectors of dyT); each dw element is summed by one task in a fixed order, and the groups are
// added in group order, so the bits do not depend on threads. The chunk comes from the L2 size
// (conv_tuning.h): a chunk's dyT rows are re-read for every block of taps.
// Triples of taps for conv_weight_grad_shift: the 3 undilated taps along the innermost storage
// axis (original axis `inner`) of each other tap, whose windows are 0, 1, 2 floats apart. Empty
// when the kernel has no such axis or the offsets do not line up (phase-split strided copies).
struct ShiftTriples {
  std::vector<int64_t> offset, tap;
  int64_t step = 0;
};

ShiftTriples shift_triples(const ConvGeometry& g, int inner, const std::vector<int64_t>& taps) {
  ShiftTriples t;
  if (inner < 0 || g.k[inner] != 3 || g.dil[inner] != 1) return t;
  t.step = 1;
  for (int a = inner + 1; a < 3; ++a) t.step *= g.k[a];
  for (int64_t r = 0; r < g.rows(); ++r) {
    if ((r / t.step) % 3 != 0) continue;
    if (taps[r + t.step] != taps[r] + 1 || taps[r + 2 * t.step] != taps[r] + 2) return ShiftTriples{};
    t.offset.push_back(taps[r]);
    t.tap.push_back(r);
  }
  return t;
}

void weight_grad_outer(const ConvGeometry& g, const Padded& xp, const std::vector<int64_t>& taps,
                       const float* dy_base, int64_t dy_pitch, int64_t len_total, float* dw, int inner_axis) {
  const int64_t R = g.rows(), vectors = (g.O + 15) / 16, Op = 16 * vectors;
  const Scratch dyT = make_scratch(g.N * len_total * Op);
  {
    constexpr int64_t kBlock = 256;  // positions per transpose task
    const int64_t blocks = (len_total + kBlock - 1) / kBlock;
    parallel_for(g.N * blocks, grain_for(Op * kBlock), [&](int64_t b0, int64_t b1) {
      for (int64_t b = b0; b < b1; ++b) {
        const int64_t n = b / blocks, q0 = b % blocks * kBlock, cnt = std::min(kBlock, len_total - q0);
        float* dst = dyT.get() + (n * len_total + q0) * Op;
        if (Op != g.O)
          for (int64_t q = 0; q < cnt; ++q) std::fill(dst + q * Op + g.O, dst + (q + 1) * Op, 0.0f);
        transpose_copy(dy_base + n * g.O * dy_pitch + q0, dy_pitch, g.O, cnt, dst, Op);
      }
    });
  }
  const WeightGradSplit split_work = weight_grad_split(g.N, len_total, weight_grad_chunk());
  const int64_t kChunk = split_work.chunk, chunks = split_work.chunks, tasks = split_work.tasks;
  const int64_t memory_cap = std::max<int64_t>(1, (int64_t{16} << 20) / (Op * R * 4));
  const int64_t items_per_call = split_work.items_per_call, calls = split_work.calls;
  const int64_t groups = std::min({calls, int64_t{16}, memory_cap});  // 16: even split over 2-4 threads
  constexpr int64_t kTapTile = 24;  // a multiple of every register tile's tap count (6, 8, 12)
  const int64_t tiles = (R + kTapTile - 1) / kTapTile;
  const int64_t parts = groups >= 8 ? 1 : std::min(tiles, (16 + groups - 1) / groups);
  const Scratch partial = make_scratch(groups * R * Op);
  const ShiftTriples tri = shift_triples(g, inner_axis, taps);
  if (vectors == 1 && !tri.offset.empty()) {
    // Blocks of 8 triples (the kernel's tile) split over the tasks like the tap tiles below.
    const int64_t count = static_cast<int64_t>(tri.offset.size()), blocks = (count + 7) / 8;
    const int64_t split = groups >= 8 ? 1 : std::min(blocks, (16 + groups - 1) / groups);
    std::fill(partial.get(), partial.get() + groups * R * Op, 0.0f);
    parallel_for(groups * split, grain_for(Op * R * len_total * g.N / (groups * split)), [&](int64_t t0, int64_t t1) {
      for (int64_t task = t0; task < t1; ++task) {
        const int64_t grp = task / split, part = task % split;
        const int64_t b0 = part * blocks / split * 8, b1 = std::min(count, (part + 1) * blocks / split * 8);
        for (int64_t call = grp * calls / groups; call < (grp + 1) * calls / groups; ++call) {
          const int64_t t = call * items_per_call, items = std::min(items_per_call, tasks - t);
          const int64_t n = t / chunks, i0 = (t % chunks) * kChunk, len = std::min(kChunk, len_total - i0);
          conv_weight_grad_shift(dyT.get() + (n * len_total + i0) * Op, Op, xp.data.get() + n * g.C * xp.volume + i0,
                                 tri.offset.data() + b0, tri.tap.data() + b0, tri.step, b1 - b0, len,
                                 partial.get() + grp * R * Op, Op, items, len_total * Op, g.C * xp.volume);
        }
      }
    });
  } else {
  parallel_for(groups * parts, grain_for(Op * R * len_total * g.N / (groups * parts)), [&](int64_t t0, int64_t t1) {
    for (int64_t task = t0; task < t1; ++task) {
      const int64_t grp = task / parts, part = task % parts;
      const int64_t k0 = part * tiles / parts * kTapTile, k1 = std::min(R, (part + 1) * tiles / parts * kTapTile);
      float* sums = partial.get() + grp * R * Op;
      std::fill(sums + k0 * Op, sums + k1 * Op, 0.0f);
      for (int64_t call = grp * calls / groups; call < (grp + 1) * calls / groups; ++call) {
        const int64_t t = call * items_per_call, items = std::min(items_per_call, tasks - t);
        const int64_t n = t / chunks, i0 = (t % chunks) * kChunk, len = std::min(kChunk, len_total - i0);
        conv_weight_grad_outer(dyT.get() + (n * len_total + i0) * Op, Op, vectors,
                               xp.data.get() + n * g.C * xp.volume + i0, taps.data() + k0, k1 - k0, len,
                               sums + k0 * Op, Op, items, len_total * Op, g.C * xp.volume);
      }
    }
  });
  }
  // dw[o][r] = Σ_grp partial[grp][r][o], groups in order; 16 taps per step.
  parallel_for((R + 15) / 16, grain_for(16 * Op * groups), [&](int64_t r0, int64_t r1) {
    alignas(64) float block[16 * 16];
    for (int64_t rb = r0; rb < r1; ++rb) {
      const int64_t ra = rb * 16, nr = std::min<int64_t>(16, R - ra);
      for (int64_t o0 = 0; o0 < g.O; o0 += 16) {
        for (int64_t r = 0; r < nr; ++r) {
          __m512 acc = _mm512_loadu_ps(partial.get() + (ra + r) * Op + o0);
          for (int64_t grp = 1; grp < groups; ++grp)
            acc = _mm512_add_ps(acc, _mm512_loadu_ps(partial.get() + (grp * R + ra + r) * Op + o0));
          _mm512_store_ps(block + r * 16, acc);
        }
        const int64_t no = std::min<int64_t>(16, g.O - o0);
        for (int64_t o = 0; o < no; ++o)
          for (int64_t r = 0; r < nr; ++r) dw[(o0 + o) * R + ra + r] = block[r * 16 + o];
      }
    }
  });
}
#endif

// dw[o][tap] = Σ_n Σ_q dy[n][o][q] · x_padded[n][tap offset + q] over the output positions q on
// the padded pitch, where dy is zero at the dropped positions. Flat chunks of each batch item are
// cut into a number of groups fixed by the shapes; each group sums its chunks in order into its
// own partial, and the partials are added in group order: the bits never depend on threads.
// padded_dy, when given, is dy padded for the input gradient of a "same" convolution: it has
// exactly the padded input's extents, with dy starting `pad` positions in on every axis.
// taps: the offset of each kernel tap in xp (tap_offsets, or phase_tap_offsets for a strided copy).
void weight_grad(const ConvGeometry& g, const Order& order, const Padded& xp, const std::vector<int64_t>& taps,
                 const float* dy, float* dw, const Padded* padded_dy, bool phased = false) {
  const int64_t R = g.rows(), Hp = xp.ext[1], Wp = xp.ext[2];
  const Axes out = permute(g.out, order);
  const int64_t flat = out[0] * Hp * Wp, len_total = (out[0] - 1) * Hp * Wp + (out[1] - 1) * Wp + out[2];
  const float* dy_base = nullptr;
  int64_t dy_pitch = flat;  // floats per (n, o) plane of the padded dy
  Padded own;
  if (padded_dy) {
    const Axes lo = permute(g.pad, order);
    dy_base = padded_dy->data.get() + (lo[0] * Hp + lo[1]) * Wp + lo[2];
    dy_pitch = padded_dy->volume;
  } else {
    own = pad_copy(dy, g.N * g.O, g.out_plane(), out, permute(out_strides(g), order), {0, 0, 0}, {out[0], Hp, Wp});
    dy_base = own.data.get();
  }
#if defined(__AVX512F__)
  return weight_grad_outer(g, xp, taps, dy_base, dy_pitch, len_total, dw, phased ? -1 : order[2]);
#endif
  // Up to 1024 positions per task: 8 rows of dy (32 KiB) stay in L1 across taps.
  const WeightGradSplit split_work = weight_grad_split(g.N, len_total, 1024);
  const int64_t kChunk = split_work.chunk, chunks = split_work.chunks, tasks = split_work.tasks;
  // Partials are capped at 16 MiB: deep layers (512 channels × 4608 taps on a few positions)
  // would otherwise spend longer zeroing and adding partials than computing. Parallelism then
  // comes from splitting the output channels (8-row blocks) of each group across tasks, which
  // keeps every dw element summed by one task in a fixed order.
  const int64_t memory_cap = std::max<int64_t>(1, (int64_t{16} << 20) / (g.O * R * 4));
  // Items shorter than a chunk (a ResNet's 8×16 stage: 142 positions on the padded pitch) are
  // grouped, up to a chunk's worth (their dy rows stay in L1 as one chunk's do), into one kernel
  // call that sums them on the same accumulators: one reduction per group instead of one per item.
  const int64_t items_per_call = split_work.items_per_call, calls = split_work.calls;
  const int64_t groups = std::min({calls, int64_t{16}, memory_cap});  // 16: even split over 2-4 threads
  const int64_t row_blocks = (g.O + kBlockRows - 1) / kBlockRows;
  const int64_t parts = groups >= 8 ? 1 : std::min(row_blocks, (16 + groups - 1) / groups);
  // One group sums straight into dw (zeroed first): no partials to zero and add.
  std::vector<float> partial(groups > 1 ? static_cast<size_t>(groups * g.O * R) : 0, 0.0f);
  float* const sums = groups > 1 ? partial.data() : dw;
  if (groups == 1) std::fill(dw, dw + g.O * R, 0.0f);
  parallel_for(groups * parts, grain_for(g.O * R * len_total * g.N / (groups * parts)), [&](int64_t t0, int64_t t1) {
    for (int64_t task = t0; task < t1; ++task) {
      const int64_t grp = task / parts, part = task % parts;
      const int64_t o0 = part * row_blocks / parts * kBlockRows;
      const int64_t o1 = std::min(g.O, (part + 1) * row_blocks / parts * kBlockRows);
      for (int64_t call = grp * calls / groups; call < (grp + 1) * calls / groups; ++call) {
        const int64_t t = call * items_per_call, items = std::min(items_per_call, tasks - t);
        const int64_t n = t / chunks, i0 = (t % chunks) * kChunk, len = std::min(kChunk, len_total - i0);
        conv_weight_grad_window(dy_base + (n * g.O + o0) * dy_pitch + i0, dy_pitch, o1 - o0,
                                xp.data.get() + n * g.C * xp.volume + i0, taps.data(), R, len,
                                sums + (grp * g.O + o0) * R, items, g.O * dy_pitch, g.C * xp.volume);
      }
    }
  });
  if (groups > 1) sum_groups(partial.data(), groups, g.O * R, dw);
}

}  // namespace

struct PaddedInput {
  Padded copy;
};

namespace {

// The kept copy when there is one, else a fresh one (returned through `own`).
const Padded& padded_x(const ConvGeometry& g, const Order& order, const float* x, const PaddedInput* kept,
                       Padded& own) {
  if (kept) return kept->copy;
  own = pad_input(g, order, x);
  return own;
}

}  // namespace

bool direct_input_grad_supported(const ConvGeometry& g) {
  for (int a = 0; a < 3; ++a)
    if (g.stride[a] != 1 || g.dil[a] * (g.k[a] - 1) - g.pad[a] < 0) return false;
  return true;
}

void direct_forward(const ConvGeometry& g, const float* x, const float* packed_w, const float* b, float* y,
                    KeptInput* keep, ForwardPanels how) {
  const Order order = storage_order(g);
  auto xp = std::make_shared<PaddedInput>(PaddedInput{pad_input(g, order, x)});
  forward_padded(g, order, xp->copy, tap_offsets(g, order, xp->copy), packed_w, b, y, how);
  // Only a reordered copy is worth holding: it is a strided gather, while a plain padded copy is
  // a contiguous one that costs less than the memory it would pin (ResNet-18 ran 2% slower).
  if (keep && order != Order{0, 1, 2}) *keep = std::move(xp);
}

ForwardPanels chosen_forward_panels(const ConvGeometry& g, bool strided) {
  const Order order = strided ? Order{0, 1, 2} : storage_order(g);
  const int64_t s = phase_stride(g);
  const int64_t pitch = strided ? (g.in[2] + 2 * g.pad[2] + s - 1) / s : permute(padded_extents(g, order), order)[2];
  return by_rows(g, order, pitch, ForwardPanels::kChoose) ? ForwardPanels::kRows : ForwardPanels::kPitch;
}

bool direct_winograd_supported(const ConvGeometry& g) { return winograd_applies(g, storage_order(g)); }

void direct_forward_winograd(const ConvGeometry& g, const float* x, const float* w, const float* b, float* y,
                             KeptInput* keep) {
  const Order order = storage_order(g);
  PaddedWinograd pw = pad_input_winograd(g, order, x);
  auto xp = std::make_shared<PaddedInput>(PaddedInput{std::move(pw.xp)});
  forward_winograd(g, order, xp->copy, w, b, y, false, &pw.u);
  if (keep && order != Order{0, 1, 2}) *keep = std::move(xp);
}

void direct_backward_input(const ConvGeometry& g, const float* w, const float* dy, float* dx) {
  const Order order = storage_order(g);
  const PaddedWinograd pd = pad_output_grad(g, order, dy);
  input_grad_from(g, order, pd.xp, w, dx, pd.u.data ? &pd.u : nullptr);
}

void direct_backward_weight(const ConvGeometry& g, const float* x, const float* dy, float* dw,
                            const PaddedInput* kept) {
  const Order order = storage_order(g);
  Padded own;
  const Padded& xp = padded_x(g, order, x, kept, own);
  weight_grad(g, order, xp, tap_offsets(g, order, xp), dy, dw, nullptr);
}

// For a "same" convolution the padded dy made for the input gradient has exactly the padded
// input's extents, so the weight gradient reads it too instead of making a second copy of dy.
bool direct_backward_fused(const ConvGeometry& g, const float* x, const float* w, const float* dy, float* dx,
                           float* dw, const PaddedInput* kept) {
  for (int a = 0; a < 3; ++a)
    if (g.stride[a] != 1 || g.dil[a] * (g.k[a] - 1) != 2 * g.pad[a]) return false;
  const Order order = storage_order(g);
  const PaddedWinograd pd = pad_output_grad(g, order, dy);
  const Padded& padded_dy = pd.xp;
  input_grad_from(g, order, padded_dy, w, dx, pd.u.data ? &pd.u : nullptr);
  Padded own;
  const Padded& xp = padded_x(g, order, x, kept, own);
  weight_grad(g, order, xp, tap_offsets(g, order, xp), dy, dw, &padded_dy);
  return true;
}

bool direct_strided_supported(const ConvGeometry& g) {
  const int64_t s = g.stride[1];
  return g.in[0] == 1 && g.k[0] == 1 && g.stride[0] == 1 && g.pad[0] == 0 && s >= 2 && g.stride[2] == s &&
         g.dil[1] == 1 && g.dil[2] == 1 && g.k[1] >= s && g.k[2] >= s;
}

void direct_forward_strided(const ConvGeometry& g, const float* x, const float* packed_w, const float* b, float* y,
                            ForwardPanels how) {
  SL_CHECK(direct_strided_supported(g), "conv: the phase-split forward needs a 2-D stride >= 2 convolution");
  const Padded xp = phase_copy(g, x);
  forward_padded(g, Order{0, 1, 2}, xp, phase_tap_offsets(g, xp), packed_w, b, y, how);
}

void direct_backward_weight_strided(const ConvGeometry& g, const float* x, const float* dy, float* dw) {
  SL_CHECK(direct_strided_supported(g), "conv: the phase-split weight gradient needs a 2-D stride >= 2 convolution");
  const Padded xp = phase_copy(g, x);
  weight_grad(g, Order{0, 1, 2}, xp, phase_tap_offsets(g, xp), dy, dw, nullptr, true);
}

}  // namespace sl::nn::detail
