#include "nn/layers_resample.h"

#include "nn/pooling.h"
#include "nn/upsample.h"

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

PoolNd::PoolNd(const char* type_name, int spatial_dims, bool is_max, int64_t kernel, int64_t stride,
               int64_t padding)
    : Module(type_name), dims_(spatial_dims), max_(is_max), kernel_(kernel), stride_(stride == 0 ? kernel : stride),
      padding_(padding) {
  SL_CHECK(kernel >= 1 && stride >= 0 && padding >= 0, type_name, ": kernel ", kernel, " must be >= 1, stride ",
           stride, " and padding ", padding, " >= 0");
}

Tensor PoolNd::forward(const Tensor& x) {
  SL_CHECK(x.dim() == dims_ + 2, type_name(), ": expected a rank-", dims_ + 2, " input, got ", x.describe());
  const int64_t k = kernel_, s = stride_, p = padding_;
  if (dims_ == 2) return max_ ? max_pool2d(x, {k, k}, {s, s}, {p, p}) : avg_pool2d(x, {k, k}, {s, s}, {p, p});
  return max_ ? max_pool3d(x, {k, k, k}, {s, s, s}, {p, p, p}) : avg_pool3d(x, {k, k, k}, {s, s, s}, {p, p, p});
}

Tensor GlobalAvgPool::forward(const Tensor& x) { return global_avg_pool(x); }

}  // namespace sl::nn
