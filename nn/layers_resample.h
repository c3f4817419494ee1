// Resampling modules: Upsample, MaxPool2d/3d, AvgPool2d/3d, GlobalAvgPool.
//
// Contract:
// - Upsample(scale, mode, align_corners): integer scale >= 1; mode "nearest" or "linear"
//   (bilinear for [N, C, H, W], trilinear for [N, C, D, H, W], as torch's "bilinear" /
//   "trilinear"); the spatial rank is taken from the input. Other ranks or modes throw.
// - MaxPool2d/AvgPool2d(kernel, stride = kernel, padding = 0) and the 3d versions: square /
//   cubic windows, PyTorch semantics of nn/pooling.h (floor mode; avg counts padding).
//   A stride of 0 means "same as kernel" (PyTorch's default stride=None).
// - GlobalAvgPool: [N, C, ...] -> [N, C].
// - None of these has parameters or buffers.
#pragma once
#include <string>

#include "nn/module.h"

namespace sl::nn {

class Upsample : public Module {
 public:
  explicit Upsample(int64_t scale, std::string mode = "nearest", bool align_corners = false);
  Tensor forward(const Tensor& x) override;

 private:
  int64_t scale_;
  std::string mode_;
  bool align_corners_;
};

// Shared by the four pooling modules.
class PoolNd : public Module {
 public:
  Tensor forward(const Tensor& x) override;

 protected:
  PoolNd(const char* type_name, int spatial_dims, bool is_max, int64_t kernel, int64_t stride, int64_t padding);

 private:
  int dims_;
  bool max_;
  int64_t kernel_, stride_, padding_;
};

class MaxPool2d : public PoolNd {
 public:
  explicit MaxPool2d(int64_t kernel, int64_t stride = 0, int64_t padding = 0)
      : PoolNd("MaxPool2d", 2, true, kernel, stride, padding) {}
};
class AvgPool2d : public PoolNd {
 public:
  explicit AvgPool2d(int64_t kernel, int64_t stride = 0, int64_t padding = 0)
      : PoolNd("AvgPool2d", 2, false, kernel, stride, padding) {}
};
class MaxPool3d : public PoolNd {
 public:
  explicit MaxPool3d(int64_t kernel, int64_t stride = 0, int64_t padding = 0)
      : PoolNd("MaxPool3d", 3, true, kernel, stride, padding) {}
};
class AvgPool3d : public PoolNd {
 public:
  explicit AvgPool3d(int64_t kernel, int64_t stride = 0, int64_t padding = 0)
      : PoolNd("AvgPool3d", 3, false, kernel, stride, padding) {}
};

class GlobalAvgPool : public Module {
 public:
  GlobalAvgPool() : Module("GlobalAvgPool") {}
  Tensor forward(const Tensor& x) override;
};

}  // namespace sl::nn
