// The object's pixels as a dense window of the image, for neighbourhood reads: a pixel list
// (ascending image indices, e.g. Foreground::pixels) and the image width give each pixel's
// 2D neighbours in O(1). Internal to render/.
//
// Contract: for_neighbours(p, r, f) calls f(q) for every listed pixel q in the (2r+1)² square
// around pixel p (p itself included), in row-major order; pixels outside the list are skipped.
#pragma once
#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <vector>

namespace sl::render::insertion {

class PixelWindow {
 public:
  PixelWindow(const std::vector<int64_t>& pixels, int64_t width) : pixels_(pixels), width_(std::max<int64_t>(1, width)) {
    if (pixels.empty()) return;
    x0_ = width_;
    x1_ = -1;
    for (const int64_t q : pixels) {
      x0_ = std::min(x0_, q % width_);
      x1_ = std::max(x1_, q % width_);
    }
    y0_ = pixels.front() / width_;
    y1_ = pixels.back() / width_;
    stride_ = x1_ - x0_ + 1;
    index_.assign(size_t(stride_ * (y1_ - y0_ + 1)), -1);
    for (size_t p = 0; p < pixels.size(); ++p) index_[slot(pixels[p] % width_, pixels[p] / width_)] = int32_t(p);
  }

  template <class F>
  void for_neighbours(size_t p, int r, F&& f) const {
    const int64_t x = pixels_[p] % width_, y = pixels_[p] / width_;
    for (int64_t yy = std::max(y0_, y - r); yy <= std::min(y1_, y + r); ++yy)
      for (int64_t xx = std::max(x0_, x - r); xx <= std::min(x1_, x + r); ++xx) {
        const int32_t q = index_[slot(xx, yy)];
        if (q >= 0) f(size_t(q));
      }
  }

 private:
  size_t slot(int64_t x, int64_t y) const { return size_t((y - y0_) * stride_ + (x - x0_)); }

  const std::vector<int64_t>& pixels_;
  int64_t width_;
  int64_t x0_ = 0, x1_ = -1, y0_ = 0, y1_ = -1, stride_ = 0;
  std::vector<int32_t> index_;  // window slot → position in pixels_ (−1: not listed)
};

}  // namespace sl::render::insertion
