// PNG strips. See image_strip.h.
#include "train/image_strip.h"

#include <algorithm>
#include <cmath>

#include "data/image_io.h"

using sl::data::ImageWriteOptions;
using sl::data::Transfer;
using sl::data::write_image;

namespace sl::train {

void write_strip(const std::string& path, const std::vector<Tensor>& images, int64_t width) {
  std::vector<Tensor> rows;
  int64_t total_h = 0;
  for (const Tensor& im : images) {
    if (!im.defined()) continue;
    SL_CHECK(im.dim() == 3 && im.size(0) == 3, "write_strip: images must be [3, H, W], got ", im.describe());
    const Tensor f = im.detach().to(DType::F32).contiguous();
    const int64_t h = std::max<int64_t>(1, f.size(1) * width / f.size(2));
    rows.push_back(f);
    total_h += h;
  }
  if (rows.empty()) return;
  Tensor out = Tensor::zeros({3, total_h, width});
  float* o = out.data<float>();
  int64_t y0 = 0;
  for (const Tensor& f : rows) {
    const int64_t sh = f.size(1), sw = f.size(2), h = std::max<int64_t>(1, sh * width / sw);
    const float* s = f.data<float>();
    for (int64_t c = 0; c < 3; ++c)
      for (int64_t y = 0; y < h; ++y)
        for (int64_t x = 0; x < width; ++x) {
          const int64_t sy = std::min(sh - 1, y * sh / h), sx = std::min(sw - 1, x * sw / width);
          const float v = s[(c * sh + sy) * sw + sx];
          o[(c * total_h + y0 + y) * width + x] = std::isfinite(v) ? std::clamp(v, 0.0f, 1.0f) : 0.0f;
        }
    y0 += h;
  }
  write_image(path, out, ImageWriteOptions{.transfer = Transfer::Linear});
}

}  // namespace sl::train
