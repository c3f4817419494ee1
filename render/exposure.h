// Exposure from the median luminance: the one rule that normalises linear radiance before the
// paper's LDR (Sec 3.4), shared by the path tracer's PNGs, the street generator's views, the
// evaluation crops and the real-panorama training crops.
//
// Requires: an F32 RGB image [3, H, W] (any layout) with at least one pixel.
// Guarantees: median_luminance() is the upper median (element n/2 after sorting) of the Rec. 709
// luminance (util/math.h); exposure_for_ldr_median() is util/math.h's exposure_for_median() of it.
// Throws: sl::Error naming the function and the shape otherwise.
#pragma once
#include "autodiff/tensor.h"

namespace sl::render {

double median_luminance(const Tensor& image);
// The exposure that maps the image's median luminance to the LDR value `ldr_median`.
double exposure_for_ldr_median(const Tensor& image, double ldr_median);

}  // namespace sl::render
