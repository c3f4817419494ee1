// A small PNG strip of predictions for a person to look at (input, true sky, predicted sky,
// composite): images stacked top to bottom, each resized (nearest) to a common width.
//
// Requires: display-ready images [3, H, W] with values in [0, 1] (LDR; written as codes, no
// extra sRGB curve). Undefined tensors are skipped. Written atomically via data/image_io.h.
#pragma once
#include <string>
#include <vector>

#include "autodiff/tensor.h"

namespace sl::train {

void write_strip(const std::string& path, const std::vector<Tensor>& images, int64_t width = 256);

}  // namespace sl::train
