#include "render/exposure.h"

#include <algorithm>
#include <vector>

#include "util/error.h"
#include "util/math.h"

namespace sl::render {

double median_luminance(const Tensor& image) {
  SL_CHECK(image.defined() && image.dim() == 3 && image.size(0) == 3 && image.dtype() == DType::F32,
           "median_luminance: expected an F32 RGB image [3, H, W], got ", image.defined() ? image.describe() : "undefined");
  const Tensor c = image.contiguous();
  const int64_t n = c.size(1) * c.size(2);
  SL_CHECK(n > 0, "median_luminance: empty image ", c.describe());
  const float* p = c.data<float>();
  std::vector<double> lum(static_cast<size_t>(n));
  for (int64_t i = 0; i < n; ++i) lum[static_cast<size_t>(i)] = luminance(p[i], p[n + i], p[2 * n + i]);
  std::nth_element(lum.begin(), lum.begin() + n / 2, lum.end());
  return lum[static_cast<size_t>(n / 2)];
}

double exposure_for_ldr_median(const Tensor& image, double ldr_median) {
  return exposure_for_median(median_luminance(image), ldr_median);
}

}  // namespace sl::render
