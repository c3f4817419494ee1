// An 8-bit LDR panorama as the bench commands that crop it by hand read it (visible-sun, sun-glare):
// its codes / 255, area-resampled to the benchmark's working width when wider
// (train::kLdrWorkingWidth, 1024), raised to kLdrGamma: linear radiance [3, H, W] F32, so that crops are
// resampled in radiance and re-encoded (data::to_ldr) as the benchmark's crops are.
// Throws sl::Error naming the file when it cannot be read.
#pragma once
#include <string>

#include "autodiff/ops.h"
#include "data/image_io.h"
#include "data/panorama.h"
#include "train/real_sky_benchmark.h"
#include "util/math.h"

namespace sl::bench {

inline Tensor read_ldr_panorama_radiance(const std::string& path) {
  data::ImageReadOptions ro;
  ro.channels = 3;
  ro.transfer = data::Transfer::Linear;
  Tensor pano = data::read_image(path, ro).to(DType::F32).contiguous();
  if (pano.size(2) > train::kLdrWorkingWidth)
    pano = data::resize_area(pano, train::kLdrWorkingWidth / 2, train::kLdrWorkingWidth);
  return pow_scalar(pano, kLdrGamma).contiguous();
}

}  // namespace sl::bench
