// Winograd F(2, 3) along one axis of a convolution (internal to nn/functional/conv*.cpp).
//
// Contract: for an axis a with 3 undilated taps and stride 1, a pair of outputs y0, y1 from four
// consecutive padded inputs d0..d3 and the taps g0..g2 is
//   y0 = m1 + m2 + m3,  y1 = m2 − m3 − m4,  where
//   m1 = (d0 − d2)·g0,  m2 = (d1 + d2)·(g0 + g1 + g2)/2,  m3 = (d2 − d1)·(g0 − g1 + g2)/2,  m4 = (d1 − d3)·g2
// (Lavin and Gray, "Fast Algorithms for Convolutional Neural Networks", CVPR 2016): four products
// per pair instead of six. Summed over the channels and the other axes' taps, each m_i is a GEMM
// of the transformed weights V_i (winograd_weights) with the transformed inputs U_i (u1 = d0 − d2,
// u2 = d1 + d2, u3 = d2 − d1, u4 = d1 − d3 at every even position). y0 does not depend on d3.
// Rounding differs from the direct sum: a tap's error scales with its row's Σ|g| rather than its
// own |g| (tests/nn/conv_test.cpp bounds both against float64).
//
// Two users: the implicit GEMM transforms a whole padded copy (conv_padding.cpp), and
// winograd_rows_forward below gathers the pairs of 2-D convolutions with few positions into
// dense panels.
#pragma once
#include <array>

#include "nn/functional/conv_geometry.h"
#include "nn/functional/conv_microkernel.h"

namespace sl::nn::detail {

// V_i[o][r] for r = (c, the other axes' taps in weight order), in pack_rows' layout, from
// w [O][C][k0][k1][k2], or with `flipped` from the kernel whose flipped transpose g convolves with
// (w [C][O][taps], tap k of (o, c) = w[c][o][taps − 1 − k]: an input gradient); `axis` (0-2) is the
// transformed one (g.k[axis] == 3). The four sets share one block, large enough for the buffer cache.
struct WinogradWeights {
  CachedFloats storage;
  int64_t stride = 0;  // floats per set
  const float* data(int64_t i) const { return storage.get() + i * stride; }
};
WinogradWeights winograd_weights(const ConvGeometry& g, int axis, const float* w, bool flipped = false);

// u1..u4 of `pairs` pairs from the padded row d (read up to d[2·pairs + 1], and with AVX-512 up to
// d[2·ceil(pairs / 16)·16 + 33]: give d that slack): component i at u + i·comp.
void winograd_pairs(const float* d, int64_t pairs, float* u, int64_t comp);

// 2-D convolutions (depth 1) with stride 1 and 3 undilated taps along the image's last axis, of
// at most 64 MiB of gathered pairs: y = conv(x, w) + b (b may be null) with every pair of one
// image row's outputs a column of dense 48-column panels (items, rows and pairs folded together),
// so a ResNet's 8 × 16 stage wastes no columns on row padding. Panels are 48 columns, or 32 where
// that fits better (a 4 × 8 stage at batch 4: 64 pairs); supported where the last panel leaves at
// most 15% of the columns empty.
// w: [O][C][kh][3] (flipped: see winograd_weights), not packed. Each output is one fixed sequence
// of operations whatever the thread count.
bool winograd_rows_supported(const ConvGeometry& g);
void winograd_rows_forward(const ConvGeometry& g, const float* x, const float* w, const float* b, float* y,
                           bool flipped = false);

}  // namespace sl::nn::detail
