#include "nn/functional/conv_padding.h"

#include <algorithm>
#include <vector>

#if defined(__AVX512F__)
#include <immintrin.h>
#endif

#include "nn/functional/conv_winograd.h"
#include "nn/functional/work_grain.h"
#include "util/parallel.h"

namespace sl::nn::detail {

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

Padded pad_copy(const float* src, int64_t planes, int64_t src_plane, const Axes& src_ext, const Axes& src_stride,
                const Axes& lo, const Axes& ext, const PlaneDone& after) {
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

bool winograd_applies(const ConvGeometry& g, const Order& order) {
  const int a = order[2];
  return g.stride[0] == 1 && g.stride[1] == 1 && g.stride[2] == 1 && g.k[a] == 3 && g.dil[a] == 1 &&
         g.out[a] >= 32 && g.N * g.out_plane() >= 4096;
}

Axes padded_extents(const ConvGeometry& g, const Order& order) {  // original axis order
  Axes padded{};
  for (int a = 0; a < 3; ++a) {
    const bool shared = a == order[2] && g.pad[a] <= g.dil[a] * (g.k[a] - 1) && g.pad[a] + kPanelCols <= kSlack;
    padded[a] = g.in[a] + (shared ? 1 : 2) * g.pad[a];
    if (a == order[2] && winograd_applies(g, order)) padded[a] += padded[a] % 2;  // one more zero column
  }
  return padded;
}

Padded pad_input(const ConvGeometry& g, const Order& order, const float* x, const PlaneDone& after) {
  return pad_copy(x, g.N * g.C, g.in_plane(), permute(g.in, order), permute(in_strides(g), order),
                  permute(g.pad, order), permute(padded_extents(g, order), order), after);
}

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

PaddedWinograd pad_output_grad(const ConvGeometry& g, const Order& order, const float* dy) {
  const ConvGeometry t = input_grad_geometry(g);
  if (winograd_applies(t, order)) return pad_input_winograd(t, order, dy);
  return PaddedWinograd{pad_input(t, order, dy), {}};
}

}  // namespace sl::nn::detail
