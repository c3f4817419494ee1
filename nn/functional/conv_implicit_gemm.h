// Stride-1 float convolution as an implicit GEMM on padded windows (internal to nn/functional/conv.cpp).
//
// Contract: for a float ConvGeometry with stride 1 on every axis (any padding, dilation and
// kernel), these compute exactly what conv.cpp's reference path computes, up to float rounding:
//   forward:        y = conv(x, w) + b                     (b may be null; w packed by the caller)
//   backward_input: dx = conv(dy, flipped wᵀ)              (needs dilation·(k - 1) >= pad)
//   backward_weight: dw = Σ dy ⊗ windows of x
//   backward_fused:  dx and dw of a "same" convolution (dilation·(k - 1) = 2·pad), sharing one
//                    padded copy of dy; returns false (nothing written) for other shapes.
// Every output element is produced by one fixed sequence of operations whatever the thread
// count, and the weight gradient is summed over fixed groups in a fixed order, so results are
// bitwise identical for any OMP_NUM_THREADS. Requires gemm_kernel_available().
//
// How: the input is zero-padded once into a scratch copy whose spatial axes are stored in an
// order chosen per shape (see conv_padding.h). Output positions are enumerated on the padded
// row pitch, so that each kernel tap of 48 consecutive positions is one contiguous window of
// the copy and the micro-kernel of conv_gemm.h streams it directly: no column matrix.
//
// Keeping the forward's copy: the weight gradient reads the same padded (and possibly reordered)
// copy of x that the forward made. When the caller passes `keep` and the copy is reordered (a
// strided gather, see storage_order), direct_forward hands that copy over instead of releasing
// it, and the backward calls given it skip making their own: the same bits, one gather over x
// fewer, at the cost of holding the copy until the backward. A plain padded copy is not kept
// (`keep` stays empty): it is cheaper to make again than the memory it would pin.
#pragma once
#include <memory>

#include "nn/functional/conv_geometry.h"

namespace sl::nn::detail {

struct PaddedInput;  // opaque: the padded copy of x for one geometry

// How direct_forward and direct_forward_strided walk the outputs: 48-position panels along the
// padded pitch (then copied into y without the dropped positions), or each output row's panels
// written straight into y (the last one possibly a narrow tile). kChoose takes the one
// conv_window_cost (conv_microkernel.h) estimates cheaper; every output is the same FMA sequence
// either way, so all three give the same bits. The other two are for tests and benchmarks.
enum class ForwardPanels { kChoose, kRows, kPitch };
// What kChoose picks for this geometry (strided: as direct_forward_strided lays it out).
ForwardPanels chosen_forward_panels(const ConvGeometry& g, bool strided);
using KeptInput = std::shared_ptr<const PaddedInput>;

bool direct_input_grad_supported(const ConvGeometry& g);

// packed_w: the weights [O, C·taps] packed by pack_rows (autodiff/gemm_kernel.h).
// keep (optional): receives the padded copy of x for the backward calls below.
void direct_forward(const ConvGeometry& g, const float* x, const float* packed_w, const float* b, float* y,
                    KeptInput* keep = nullptr, ForwardPanels how = ForwardPanels::kChoose);
// Winograd F(2, 3) along the innermost storage axis (stride 1, 3 undilated taps on that axis;
// conv_padding.h, "Winograd"): the same contract as direct_forward, from unpacked weights
// w [O, C·taps], with 2/3 of its multiply-adds and slightly different rounding. The fused and
// input-gradient backward calls below use it by themselves where it applies.
bool direct_winograd_supported(const ConvGeometry& g);
void direct_forward_winograd(const ConvGeometry& g, const float* x, const float* w, const float* b, float* y,
                             KeptInput* keep = nullptr);
void direct_backward_input(const ConvGeometry& g, const float* w, const float* dy, float* dx);
// kept (optional): direct_forward's copy of this x for this g; x is then not read.
void direct_backward_weight(const ConvGeometry& g, const float* x, const float* dy, float* dw,
                            const PaddedInput* kept = nullptr);
bool direct_backward_fused(const ConvGeometry& g, const float* x, const float* w, const float* dy, float* dx,
                           float* dw, const PaddedInput* kept = nullptr);

// Strided 2-D convolutions (in[0] = k[0] = 1, the same stride s >= 2 on both image axes, dilation 1,
// a kernel at least s wide): the forward and the weight gradient on the same window kernels, from a
// copy of x split into its s × s phases (conv_padding.h, "Strided"). The forward gives the
// bits of the im2col panel path (the same FMA sequence per output); the weight gradient is summed in
// fixed chunks of the phase pitch.
bool direct_strided_supported(const ConvGeometry& g);
void direct_forward_strided(const ConvGeometry& g, const float* x, const float* packed_w, const float* b, float* y,
                            ForwardPanels how = ForwardPanels::kChoose);
void direct_backward_weight_strided(const ConvGeometry& g, const float* x, const float* dy, float* dw);

}  // namespace sl::nn::detail
