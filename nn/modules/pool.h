// Pooling modules: MaxPool2d/3d, AvgPool2d/3d (over PoolNd) and GlobalAvgPool.
//
// Contract: MaxPool2d/AvgPool2d(kernel, stride = kernel, padding = 0) and the 3d versions: square /
// cubic windows, PyTorch semantics of nn/functional/pooling.h (floor mode; avg counts padding).
// A stride of 0 means "same as kernel" (PyTorch's default stride=None). GlobalAvgPool:
// [N, C, ...] -> [N, C]. None has parameters or buffers.
#pragma once
#include "nn/module.h"

namespace sl::nn {

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
