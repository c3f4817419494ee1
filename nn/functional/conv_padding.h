// The zero-padded copies that the implicit GEMM's window kernels read, and their layout (internal
// to nn/functional/conv_implicit_gemm.cpp).
//
// Contract: for a float ConvGeometry,
//   storage_order:   the order in which a padded copy stores the spatial axes, outermost first;
//   pad_input:       the padded (and possibly reordered) copy of x, tap_offsets the start of each
//                    kernel tap's window in it;
//   phase_copy:      the padded copy of a strided 2-D convolution's x split into its s × s phases,
//                    phase_tap_offsets the start of each tap's window in it;
//   pad_input_winograd, winograd_input: a padded copy with its Winograd F(2, 3) transform
//                    (conv_winograd.h), winograd_tap_offsets the windows in the transform;
//   pad_output_grad: dy padded the same way for the input gradient.
// Every copy is followed by kSlack zeros, so the windows of the last positions read zeros rather
// than past the buffer. The copies move floats without arithmetic (the Winograd transform is
// conv_winograd.h's), and each plane is written by one task, so their bits do not depend on the
// thread count. Positions outside the source hold 0.
#pragma once
#include <array>
#include <cstdint>
#include <functional>
#include <vector>

#include "nn/functional/conv_geometry.h"
#include "nn/functional/conv_microkernel.h"

namespace sl::nn::detail {

using Axes = std::array<int64_t, 3>;
using Order = std::array<int, 3>;  // order[i]: the original spatial axis stored at position i

inline Axes permute(const Axes& v, const Order& order) { return {v[order[0]], v[order[1]], v[order[2]]}; }

// 64-byte aligned scratch (conv_microkernel.h), so that rows whose pitch is a multiple of 16
// floats load without splitting cache lines (it made the weight-gradient kernel 1.7× faster on 2-D
// shapes); large blocks come from the buffer cache.
using Scratch = CachedFloats;
constexpr int64_t kSlack = 2 * kPanelCols;  // windows of dropped columns may run past the end

inline Scratch make_scratch(int64_t floats) { return cached_floats(floats); }

inline Axes plane_strides(const Axes& ext) { return {ext[1] * ext[2], ext[2], 1}; }
inline Axes in_strides(const ConvGeometry& g) { return plane_strides(g.in); }
inline Axes out_strides(const ConvGeometry& g) { return plane_strides(g.out); }

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
Order storage_order(const ConvGeometry& g);

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
                const Axes& lo, const Axes& ext, const PlaneDone& after = {});

// Offset of tap r = (c, k0, k1, k2) (original order, as the weights are laid out) in a padded
// copy: channel plane plus the dilated kernel offset through the storage strides.
std::vector<int64_t> tap_offsets(const ConvGeometry& g, const Order& order, const Padded& xp);

// Whether the forward runs as Winograd F(2, 3) along the innermost storage axis (see
// forward_winograd, conv_implicit_gemm.cpp): unit stride, 3 undilated taps on that axis, and enough work to pay for the
// transforms. Rows shorter than 32 outputs waste too much of each 96-output step, and below 4096
// output positions per call the four transformed, packed weight sets cost more than the third of
// the multiply-adds saved (ResNet-18's 16×32 and 8×16 stages at batch 4: no gain and 2× slower).
// A "same" convolution and its input gradient have the same kernel and output size, so they
// agree, and the padded dy of the fused backward keeps the padded x's extents.
bool winograd_applies(const ConvGeometry& g, const Order& order);

// The innermost storage axis gets its zeros on one side only: a row is [pad zeros][in values],
// pitch in + pad. A valid output reads original columns −pad .. in − 1 + pad (stride 1, any kernel,
// dilation and padding), and the right-hand ones land in the next row's leading zeros (the last
// row's in the next plane's, or in the buffer's zero slack), so every window holds the same values
// as with zeros on both sides, while the positions dropped per row fall from 2·pad to pad: ResNet-18's
// 16-wide stage wastes 6% of its work instead of 11%. Padding wider than the kernel's reach
// (pad > dilation·(k − 1)) gives rows of more than in + pad outputs and keeps both margins, as do
// the other axes. The last plane's windows then end pad − 1 floats past the copy, plus a panel's
// overrun: the zero slack must hold both, else both margins are kept too.
Axes padded_extents(const ConvGeometry& g, const Order& order);

Padded pad_input(const ConvGeometry& g, const Order& order, const float* x, const PlaneDone& after = {});

// Strided 2-D convolutions (stride s on both image axes, dilation 1) on the same windows: the
// zero-padded input is split into its s × s phases, phase (py, px) holding padded rows py, py + s, …
// and columns px, px + s, … as a Hq × Wq plane (Hq, Wq = the padded size / s, rounded up). Output
// (oy, ox) and tap (ky, kx) read padded (s·oy + ky, s·ox + kx), which is phase (ky mod s, kx mod s)
// at (oy + ky div s, ox + kx div s): with outputs on the phase pitch Wq, every tap is again one
// contiguous window. Layout per item: [C][s·s][Hq][Wq]; ext = {s·s, Hq, Wq} (the forward and the
// weight gradient read only ext[1] and ext[2] of a 2-D geometry).
inline int64_t phase_stride(const ConvGeometry& g) { return g.stride[1]; }

Padded phase_copy(const ConvGeometry& g, const float* x);
std::vector<int64_t> phase_tap_offsets(const ConvGeometry& g, const Padded& xp);

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

PaddedWinograd pad_input_winograd(const ConvGeometry& g, const Order& order, const float* x);
WinogradInput winograd_input(const Padded& xp, int64_t N, int64_t C);

// Offset of row r = (c, other taps) of V_i in U_i: the channel plane plus the other axes' dilated
// offsets, halved (they are whole rows or planes of the even pitch).
std::vector<int64_t> winograd_tap_offsets(const ConvGeometry& g, const Order& order, const Padded& xp);

// dy padded for the input gradient, with its Winograd transform when the input gradient runs as
// Winograd (u.data empty otherwise).
PaddedWinograd pad_output_grad(const ConvGeometry& g, const Order& order, const float* dy);

}  // namespace sl::nn::detail
