#include "nn/modules/pool.h"

#include "nn/functional/pooling.h"

namespace sl::nn {

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
