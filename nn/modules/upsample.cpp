#include "nn/modules/upsample.h"

#include "nn/functional/upsample.h"

namespace sl::nn {

Upsample::Upsample(int64_t scale, std::string mode, bool align_corners)
    : Module("Upsample"), scale_(scale), mode_(std::move(mode)), align_corners_(align_corners) {
  SL_CHECK(scale >= 1, "Upsample: scale must be >= 1, got ", scale);
  SL_CHECK(mode_ == "nearest" || mode_ == "linear", "Upsample: unknown mode '", mode_,
           "' (valid: nearest, linear)");
}

Tensor Upsample::forward(const Tensor& x) {
  SL_CHECK(x.dim() == 4 || x.dim() == 5, "Upsample: expected [N, C, H, W] or [N, C, D, H, W], got ",
           x.describe());
  if (x.dim() == 4)
    return mode_ == "nearest" ? upsample_nearest2d(x, scale_) : upsample_bilinear2d(x, scale_, align_corners_);
  return mode_ == "nearest" ? upsample_nearest3d(x, scale_) : upsample_trilinear3d(x, scale_, align_corners_);
}

}  // namespace sl::nn
