// Simple photometric statistics of the network's input image, given to the sun head beside the
// backbone's features (model.sun_image_statistics, issue 53).
//
// Why: which half of the sky holds the sun is a photometric cue (a backlit scene is dark with a
// bright, saturated sky on one side; a front-lit one is bright and evenly coloured). A linear
// probe on these 102 numbers told front from back on held-out real crops at 0.71, the pooled
// ImageNet features of a MobileNetV2 at 0.62; a global average pool keeps little of where in
// the frame the light is.
//
// Contract: image [N, 3, H, W], LDR in [0, 1] (values outside are clamped), H and W at least 4,
// float32 or float64. Returns [N, kImageStatistics] in the image's dtype, per image in order:
//   - 48: the mean of each channel in each cell of a 4×4 grid (row-major cells, R G B per cell);
//   - 48: the standard deviation of each channel in each cell, same order;
//   -  2: the brightness (mean of R, G, B) of the right half minus the left half, and of the top
//         half minus the bottom half;
//   -  4: the share of saturated pixels (largest channel ≥ 250/255) in each quadrant, row-major.
// Cell and half boundaries are floor(k·H/4), floor(k·W/4). A constant of the input: it records
// nothing on the tape and has no gradient. When W is divisible by 4, mirroring the image
// horizontally mirrors the cells and quadrants and negates the right-minus-left brightness.
// Throws sl::Error naming the shape otherwise.
#pragma once
#include <cstdint>

#include "autodiff/tensor.h"

namespace sl::train {

inline constexpr int64_t kImageStatistics = 102;

Tensor image_statistics(const Tensor& image);

}  // namespace sl::train
