// Photometric statistics of the input image for the sun head. See image_statistics.h.
#include "train/image_statistics.h"

#include <algorithm>
#include <cmath>
#include <vector>

#include "util/error.h"

namespace sl::train {

Tensor image_statistics(const Tensor& image) {
  SL_CHECK(image.defined() && image.dim() == 4 && image.size(1) == 3 && image.size(2) >= 4 && image.size(3) >= 4,
           "image_statistics: expected an image [N, 3, H, W] with H, W >= 4, got ",
           image.defined() ? image.describe() : std::string("undefined"));
  const int64_t n = image.size(0), h = image.size(2), w = image.size(3);
  const std::vector<double> px = image.to_vector();
  std::vector<double> out(static_cast<size_t>(n * kImageStatistics), 0.0);
  const auto at = [&](int64_t b, int64_t c, int64_t y, int64_t x) {
    return std::clamp(px[static_cast<size_t>(((b * 3 + c) * h + y) * w + x)], 0.0, 1.0);
  };
  constexpr double kSaturated = 250.0 / 255.0;
  for (int64_t b = 0; b < n; ++b) {
    double* o = out.data() + b * kImageStatistics;
    double half_x[2] = {0, 0}, half_y[2] = {0, 0};
    int64_t half_x_n[2] = {0, 0}, half_y_n[2] = {0, 0};
    double saturated[4] = {0, 0, 0, 0};
    int64_t quadrant_n[4] = {0, 0, 0, 0};
    for (int gy = 0; gy < 4; ++gy)
      for (int gx = 0; gx < 4; ++gx) {
        const int64_t y0 = gy * h / 4, y1 = (gy + 1) * h / 4, x0 = gx * w / 4, x1 = (gx + 1) * w / 4;
        const double count = static_cast<double>((y1 - y0) * (x1 - x0));
        for (int c = 0; c < 3; ++c) {
          double sum = 0, sum2 = 0;
          for (int64_t y = y0; y < y1; ++y)
            for (int64_t x = x0; x < x1; ++x) {
              const double v = at(b, c, y, x);
              sum += v;
              sum2 += v * v;
            }
          const double mean = sum / count;
          o[(gy * 4 + gx) * 3 + c] = mean;
          o[48 + (gy * 4 + gx) * 3 + c] = std::sqrt(std::max(sum2 / count - mean * mean, 0.0));
        }
      }
    for (int64_t y = 0; y < h; ++y)
      for (int64_t x = 0; x < w; ++x) {
        const double r = at(b, 0, y, x), g = at(b, 1, y, x), bl = at(b, 2, y, x);
        const double brightness = (r + g + bl) / 3.0;
        const int right = x >= w / 2, bottom = y >= h / 2;
        half_x[right] += brightness;
        ++half_x_n[right];
        half_y[bottom] += brightness;
        ++half_y_n[bottom];
        const int q = bottom * 2 + right;
        saturated[q] += std::max({r, g, bl}) >= kSaturated;
        ++quadrant_n[q];
      }
    o[96] = half_x[1] / half_x_n[1] - half_x[0] / half_x_n[0];
    o[97] = half_y[0] / half_y_n[0] - half_y[1] / half_y_n[1];
    for (int q = 0; q < 4; ++q) o[98 + q] = saturated[q] / quadrant_n[q];
  }
  return Tensor::from_vector(out, {n, kImageStatistics}, image.dtype());
}

}  // namespace sl::train
