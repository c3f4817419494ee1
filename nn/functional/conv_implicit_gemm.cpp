#include "nn/functional/conv_implicit_gemm.h"

#include <algorithm>
#include <array>
#include <cstdlib>
#include <functional>
#include <memory>
#include <vector>

#if defined(__AVX512F__)
#include <immintrin.h>
#endif

#include "autodiff/buffer_cache.h"
#include "nn/functional/conv_microkernel.h"
#include "nn/functional/conv_tuning.h"
#include "nn/functional/conv_winograd.h"
#include "nn/functional/group_sums.h"
#include "autodiff/transpose16.h"
#include "nn/functional/work_grain.h"
#include "util/error.h"
#include "util/parallel.h"

namespace sl::nn::detail {
namespace {

using Axes = std::array<int64_t, 3>;
using Order = std::array<int, 3>;  // order[i]: the original spatial axis stored at position i

Axes permute(const Axes& v, const Order& order) { return {v[order[0]], v[order[1]], v[order[2]]}; }

// 64-byte aligned scratch (conv_microkernel.h), so that rows whose pitch is a multiple of 16
// floats load without splitting cache lines (it made the weight-gradient kernel 1.7× faster on 2-D
// shapes); large blocks come from the buffer cache.
using Scratch = CachedFloats;
constexpr int64_t kSlack = 2 * kPanelCols;  // windows of dropped columns may run past the end

Scratch make_scratch(int64_t floats) { return cached_floats(floats); }

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

// Storage order of the spatial axes, outermost first. Output positions run along the padded
// row pitch, so part of the work on the innermost axis is wasted on dropped columns (pad / (in +
// pad), since pad_input shares one zero margin between rows; the estimate below, dilation·(k − 1) /
// (in + 2·pad), is the two-margin figure it was tuned with) and, for the weight gradient, as much
// on the middle axis. By that estimate a 64×64×16 volume stored as is wastes 11% along its
// 16-deep axis (33% at the 4-deep level of a UNet); stored with a 64-long axis innermost it
// wastes 3%. The copy made for padding does the reordering,
// and the output is written back through the original strides, so reordering costs strided
// gathers and scatters: it is used only when the innermost axis wastes over 5% and another
// axis of at least 32 positions wastes less than half of that.
Order storage_order(const ConvGeometry& g) {
  auto waste = [&](int a) {
    return static_cast<double>(g.dil[a] * (g.k[a] - 1)) / static_cast<double>(g.in[a] + 2 * g.pad[a]);
  };
  if (waste(2) <= 0.05) return {0, 1, 2};
  int inner = 2;
  for (int a : {1, 0})  // axis 1 first: its smaller original stride keeps the gathers local
    if (g.out[a] >= 32 && waste(a) < 0.5 * waste(2) && (inner == 2 || waste(a) < 0.67 * waste(inner))) inner = a;
  if (inner == 2) return {0, 1, 2};
  int rest[2], n = 0;
  for (int a = 0; a < 3; ++a)
    if (a != inner) rest[n++] = a;
  if (waste(rest[1]) > waste(rest[0])) std::swap(rest[0], rest[1]);  // the more wasteful axis outermost
  return {rest[0], rest[1], inner};
}

Axes plane_strides(const Axes& ext) { return {ext[1] * ext[2], ext[2], 1}; }

// planes × [ext0][ext1][ext2] (storage order) with
//   dst[p][s] = src[p·src_plane + Σ_i (s_i - lo_i)·src_stride_i] inside the source, 0 outside.
struct Padded {
  Axes ext{};
  int64_t volume = 0;  // per plane
  Scratch data;
};


// after (optional): called with each plane's index and data as soon as that plane is complete, by
// the task that wrote it (while the plane is still in cache).
using PlaneDone = std::function<void(int64_t, const float*)>;

Padded pad_copy(const float* src, int64_t planes, int64_t src_plane, const Axes& src_ext, const Axes& src_stride,
                const Axes& lo, const Axes& ext, const PlaneDone& after = {}) {
  Padded out;
  out.ext = ext;
  out.volume = ext[0] * ext[1] * ext[2];
  out.data = make_scratch(planes * out.volume + kSlack);
  float* base = out.data.get();
  std::fill(base + planes * out.volume, base + planes * out.volume + kSlack, 0.0f);
  const int64_t lo2 = lo[2], n2 = src_ext[2];
  auto inside = [&](int64_t s, int a) { return s - lo[a] >= 0 && s - lo[a] < src_ext[a]; };
  // When the outer storage axis is the closer one in the source (a reordered copy), walk the
  // source in its own order so that reads are contiguous and the writes stay in a few rows.
  const bool transposed = src_stride[2] != 1 && src_stride[0] < src_stride[2];
  parallel_for(planes, grain_for(out.volume), [&](int64_t p0, int64_t p1) {
    for (int64_t p = p0; p < p1; ++p) {
      float* vol = base + p * out.volume;
      const float* sp = src + p * src_plane;
      for (int64_t s0 = 0; s0 < ext[0]; ++s0)
        for (int64_t s1 = 0; s1 < ext[1]; ++s1) {  // borders: zero rows and margins
          float* dst = vol + (s0 * ext[1] + s1) * ext[2];
          if (!inside(s0, 0) || !inside(s1, 1)) {
            std::fill(dst, dst + ext[2], 0.0f);
            continue;
          }
          std::fill(dst, dst + lo2, 0.0f);
          std::fill(dst + lo2 + n2, dst + ext[2], 0.0f);
          if (transposed) continue;
          const float* row = sp + (s0 - lo[0]) * src_stride[0] + (s1 - lo[1]) * src_stride[1];
          if (src_stride[2] == 1) {
            std::copy(row, row + n2, dst + lo2);
          } else {
            for (int64_t i = 0; i < n2; ++i) dst[lo2 + i] = row[i * src_stride[2]];
          }
        }
      for (int64_t s1 = lo[1]; transposed && s1 < lo[1] + src_ext[1]; ++s1) {
        const float* slab = sp + (s1 - lo[1]) * src_stride[1];
        float* dst = vol + s1 * ext[2] + lo2 + lo[0] * ext[1] * ext[2];
#if defined(__AVX512F__)
        if (src_stride[0] == 1) {
          transpose_copy(slab, src_stride[2], n2, src_ext[0], dst, ext[1] * ext[2]);
          continue;
        }
#endif
        for (int64_t i = 0; i < n2; ++i)
          for (int64_t j = 0; j < src_ext[0]; ++j) dst[j * ext[1] * ext[2] + i] = slab[i * src_stride[2] + j * src_stride[0]];
      }
      if (after) after(p, vol);
    }
  });
  return out;
}

// Offset of tap r = (c, k0, k1, k2) (original order, as the weights are laid out) in a padded
// copy: channel plane plus the dilated kernel offset through the storage strides.
std::vector<int64_t> tap_offsets(const ConvGeometry& g, const Order& order, const Padded& xp) {
  const Axes ps = plane_strides(xp.ext);
  Axes stride_of{};  // padded stride of each ORIGINAL axis
  for (int i = 0; i < 3; ++i) stride_of[order[i]] = ps[i];
  std::vector<int64_t> off(static_cast<size_t>(g.rows()));
  for (int64_t c = 0, r = 0; c < g.C; ++c)
    for (int64_t k0 = 0; k0 < g.k[0]; ++k0)
      for (int64_t k1 = 0; k1 < g.k[1]; ++k1)
        for (int64_t k2 = 0; k2 < g.k[2]; ++k2, ++r)
          off[r] = c * xp.volume + k0 * g.dil[0] * stride_of[0] + k1 * g.dil[1] * stride_of[1] +
                   k2 * g.dil[2] * stride_of[2];
  return off;
}

Axes in_strides(const ConvGeometry& g) { return plane_strides(g.in); }
Axes out_strides(const ConvGeometry& g) { return plane_strides(g.out); }

// Whether the forward runs as Winograd F(2, 3) along the innermost storage axis (see
// forward_winograd): unit stride, 3 undilated taps on that axis, and enough work to pay for the
// transforms. Rows shorter than 32 outputs waste too much of each 96-output step, and below 4096
// output positions per call the four transformed, packed weight sets cost more than the third of
// the multiply-adds saved (ResNet-18's 16×32 and 8×16 stages at batch 4: no gain and 2× slower).
// A "same" convolution and its input gradient have the same kernel and output size, so they
// agree, and the padded dy of the fused backward keeps the padded x's extents.
bool winograd_applies(const ConvGeometry& g, const Order& order) {
  const int a = order[2];
  return g.stride[0] == 1 && g.stride[1] == 1 && g.stride[2] == 1 && g.k[a] == 3 && g.dil[a] == 1 &&
         g.out[a] >= 32 && g.N * g.out_plane() >= 4096;
}

// The innermost storage axis gets its zeros on one side only: a row is [pad zeros][in values],
// pitch in + pad. A valid output reads original columns −pad .. in − 1 + pad (stride 1, any kernel,
// dilation and padding), and the right-hand ones land in the next row's leading zeros (the last
// row's in the next plane's, or in the buffer's zero slack), so every window holds the same values
// as with zeros on both sides, while the positions dropped per row fall from 2·pad to pad: ResNet-18's
// 16-wide stage wastes 6% of its work instead of 11%. Padding wider than the kernel's reach
// (pad > dilation·(k − 1)) gives rows of more than in + pad outputs and keeps both margins, as do
// the other axes. The last plane's windows then end pad − 1 floats past the copy, plus a panel's
// overrun: the zero slack must hold both, else both margins are kept too.
Axes padded_extents(const ConvGeometry& g, const Order& order) {  // original axis order
  Axes padded{};
  for (int a = 0; a < 3; ++a) {
    const bool shared = a == order[2] && g.pad[a] <= g.dil[a] * (g.k[a] - 1) && g.pad[a] + kPanelCols <= kSlack;
    padded[a] = g.in[a] + (shared ? 1 : 2) * g.pad[a];
    if (a == order[2] && winograd_applies(g, order)) padded[a] += padded[a] % 2;  // one more zero column
  }
  return padded;
}

Padded pad_input(const ConvGeometry& g, const Order& order, const float* x, const PlaneDone& after = {}) {
  return pad_copy(x, g.N * g.C, g.in_plane(), permute(g.in, order), permute(in_strides(g), order),
                  permute(g.pad, order), permute(padded_extents(g, order), order), after);
}

// Strided 2-D convolutions (stride s on both image axes, dilation 1) on the same windows: the
// zero-padded input is split into its s × s phases, phase (py, px) holding padded rows py, py + s, …
// and columns px, px + s, … as a Hq × Wq plane (Hq, Wq = the padded size / s, rounded up). Output
// (oy, ox) and tap (ky, kx) read padded (s·oy + ky, s·ox + kx), which is phase (ky mod s, kx mod s)
// at (oy + ky div s, ox + kx div s): with outputs on the phase pitch Wq, every tap is again one
// contiguous window. Layout per item: [C][s·s][Hq][Wq]; ext = {s·s, Hq, Wq} (the forward and the
// weight gradient read only ext[1] and ext[2] of a 2-D geometry).
int64_t phase_stride(const ConvGeometry& g) { return g.stride[1]; }

Padded phase_copy(const ConvGeometry& g, const float* x) {
  const int64_t s = phase_stride(g);
  const int64_t Hq = (g.in[1] + 2 * g.pad[1] + s - 1) / s, Wq = (g.in[2] + 2 * g.pad[2] + s - 1) / s;
  Padded out;
  out.ext = {s * s, Hq, Wq};
  out.volume = s * s * Hq * Wq;
  const int64_t planes = g.N * g.C;
  out.data = make_scratch(planes * out.volume + kSlack);
  float* base = out.data.get();
  std::fill(base + planes * out.volume, base + planes * out.volume + kSlack, 0.0f);
  const int64_t H = g.in[1], W = g.in[2];
  // Each source row is first copied with its zero margins into a padded row of s·Wq floats, whose
  // phase px is then every s-th float from px: no bounds test per element, and for s = 2 a vector
  // deinterleave (the per-element gather with its bounds tests was 15% of ResNet-18's
  // 64 -> 128-channel stride-2 forward, perf, 1 thread). The same values either way.
  parallel_for(planes, grain_for(out.volume), [&](int64_t p0, int64_t p1) {
    std::vector<float> padded(static_cast<size_t>(s * Wq + 32), 0.0f);
    float* const pr = padded.data();
    for (int64_t p = p0; p < p1; ++p) {
      const float* src = x + p * H * W;
      for (int64_t py = 0; py < s; ++py)
        for (int64_t i = 0; i < Hq; ++i) {
          float* const dst0 = base + p * out.volume + (py * s * Hq + i) * Wq;  // phase (py, 0); (py, px) is px·Hq·Wq further
          const int64_t y = i * s + py - g.pad[1];
          if (y < 0 || y >= H) {
            for (int64_t px = 0; px < s; ++px) std::fill(dst0 + px * Hq * Wq, dst0 + px * Hq * Wq + Wq, 0.0f);
            continue;
          }
          // pr[t] = x column t − pad[2] (0 outside the row), t < s·Wq.
          const int64_t lo = std::min(g.pad[2], s * Wq), n = std::clamp<int64_t>(s * Wq - lo, 0, W);
          std::fill(pr, pr + lo, 0.0f);
          std::copy(src + y * W, src + y * W + n, pr + lo);
          std::fill(pr + lo + n, pr + s * Wq, 0.0f);
          int64_t j = 0;
#if defined(__AVX512F__)
          if (s == 2) {
            const __m512i even = _mm512_setr_epi32(0, 2, 4, 6, 8, 10, 12, 14, 16, 18, 20, 22, 24, 26, 28, 30);
            const __m512i odd = _mm512_add_epi32(even, _mm512_set1_epi32(1));
            for (; j + 16 <= Wq; j += 16) {
              const __m512 a = _mm512_loadu_ps(pr + 2 * j), b = _mm512_loadu_ps(pr + 2 * j + 16);
              _mm512_storeu_ps(dst0 + j, _mm512_permutex2var_ps(a, even, b));
              _mm512_storeu_ps(dst0 + Hq * Wq + j, _mm512_permutex2var_ps(a, odd, b));
            }
          }
#endif
          for (int64_t px = 0; px < s; ++px)
            for (int64_t jj = j; jj < Wq; ++jj) dst0[px * Hq * Wq + jj] = pr[jj * s + px];
        }
    }
  });
  return out;
}

std::vector<int64_t> phase_tap_offsets(const ConvGeometry& g, const Padded& xp) {
  const int64_t s = phase_stride(g), Hq = xp.ext[1], Wq = xp.ext[2];
  std::vector<int64_t> off(static_cast<size_t>(g.rows()));
  for (int64_t c = 0, r = 0; c < g.C; ++c)
    for (int64_t ky = 0; ky < g.k[1]; ++ky)
      for (int64_t kx = 0; kx < g.k[2]; ++kx, ++r)
        off[r] = c * xp.volume + ((ky % s) * s + kx % s) * Hq * Wq + (ky / s) * Wq + kx / s;
  return off;
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

// Winograd F(2, 3) (conv_winograd.h) along the innermost storage axis. Each m_i is a GEMM on
// windows of one transformed copy U_i of the padded input, at half its pitch: the same
// micro-kernel, with K a third as long and 96 outputs per call, so 2/3 of the direct form's FMAs.
// The padded pitch is even (pad_input), so a row or plane step in d is a whole number of pairs in
// U. y0 does not depend on d3, so a valid output never reads past its own row's zeros.
struct WinogradInput {
  int64_t half = 0;  // floats per (item, component, channel) plane: the padded volume / 2
  Scratch data;      // [N][4][C][half], then kSlack zeros
};

// pad_input with the Winograd transform of each plane made by the task that padded it, while the
// plane is in cache, instead of in a second pass over the whole copy (a 1×16×64×64×16 input pads
// to 5 MB, past L2). The pairs whose vector loads would reach past the plane (into the next one,
// perhaps not written yet) are transformed once the copy is complete: the same values either way.
struct PaddedWinograd {
  Padded xp;
  WinogradInput u;
};

PaddedWinograd pad_input_winograd(const ConvGeometry& g, const Order& order, const float* x) {
  PaddedWinograd r;
  const Axes ext = padded_extents(g, order);
  const int64_t volume = ext[0] * ext[1] * ext[2], half = volume / 2, C = g.C, planes = g.N * C;
  // winograd_pairs(d, n, ...) with AVX-512 reads up to d[2·ceil(n / 16)·16 + 33].
  const int64_t safe = std::max<int64_t>(0, (volume - 34) / 2 / 16 * 16);
  r.u.half = half;
  r.u.data = make_scratch(planes * 4 * half + kSlack);
  float* const ubase = r.u.data.get();
  std::fill(ubase + planes * 4 * half, ubase + planes * 4 * half + kSlack, 0.0f);
  auto u_of = [&](int64_t p) { return ubase + ((p / C) * 4 * C + p % C) * half; };
  r.xp = pad_input(g, order, x, [&](int64_t p, const float* vol) { winograd_pairs(vol, safe, u_of(p), C * half); });
  const float* const xbase = r.xp.data.get();
  parallel_for(planes, grain_for(4 * (half - safe)), [&](int64_t p0, int64_t p1) {
    for (int64_t p = p0; p < p1; ++p) winograd_pairs(xbase + p * volume + 2 * safe, half - safe, u_of(p) + safe, C * half);
  });
  return r;
}

WinogradInput winograd_input(const Padded& xp, int64_t N, int64_t C) {
  WinogradInput u;
  u.half = xp.volume / 2;
  const int64_t half = u.half;
  u.data = make_scratch(N * 4 * C * half + kSlack);
  float* const base = u.data.get();
  std::fill(base + N * 4 * C * half, base + N * 4 * C * half + kSlack, 0.0f);
  // The last plane's pairs read up to 34 floats past it: the padded copy's zero slack.
  parallel_for(N * C, grain_for(2 * xp.volume), [&](int64_t p0, int64_t p1) {
    for (int64_t p = p0; p < p1; ++p) {
      const float* d = xp.data.get() + p * xp.volume;
      winograd_pairs(d, half, base + ((p / C) * 4 * C + p % C) * half, C * half);
    }
  });
  return u;
}

// Offset of row r = (c, other taps) of V_i in U_i: the channel plane plus the other axes' dilated
// offsets, halved (they are whole rows or planes of the even pitch).
std::vector<int64_t> winograd_tap_offsets(const ConvGeometry& g, const Order& order, const Padded& xp) {
  const int a = order[2];
  const Axes ps = plane_strides(xp.ext);
  Axes stride_of{};
  for (int i = 0; i < 3; ++i) stride_of[order[i]] = ps[i];
  std::vector<int64_t> off;
  off.reserve(static_cast<size_t>(g.rows() / 3));
  for (int64_t c = 0; c < g.C; ++c)
    for (int64_t k0 = 0; k0 < (a == 0 ? 1 : g.k[0]); ++k0)
      for (int64_t k1 = 0; k1 < (a == 1 ? 1 : g.k[1]); ++k1)
        for (int64_t k2 = 0; k2 < (a == 2 ? 1 : g.k[2]); ++k2)
          off.push_back(c * (xp.volume / 2) +
                        (k0 * g.dil[0] * stride_of[0] + k1 * g.dil[1] * stride_of[1] + k2 * g.dil[2] * stride_of[2]) / 2);
  return off;
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

// dy padded for the input gradient, with its Winograd transform when the input gradient runs as
// Winograd (u.data empty otherwise).
PaddedWinograd pad_output_grad(const ConvGeometry& g, const Order& order, const float* dy) {
  const ConvGeometry t = input_grad_geometry(g);
  if (winograd_applies(t, order)) return pad_input_winograd(t, order, dy);
  return PaddedWinograd{pad_input(t, order, dy), {}};
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
