#include "nn/modules/flatten.h"

#include "autodiff/ops.h"

namespace sl::nn {

Tensor Flatten::forward(const Tensor& x) {
  SL_CHECK(x.dim() > start_dim_, "Flatten(", start_dim_, "): input ", x.describe(), " has too few dims");
  return flatten(x, start_dim_, -1);
}

}  // namespace sl::nn
