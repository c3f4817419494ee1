#include "nn/modules/layer_norm.h"

#include "autodiff/ops.h"
#include "nn/init.h"

namespace sl::nn {

LayerNorm::LayerNorm(int64_t features, double eps, bool affine)
    : Module("LayerNorm"), features_(features), eps_(eps), affine_(affine) {
  SL_CHECK(features > 0 && eps > 0, "LayerNorm: features ", features, " and eps ", eps, " must be > 0");
  if (affine) {
    register_parameter("weight", Tensor::ones({features}));
    register_parameter("bias", Tensor::zeros({features}));
  }
}

void LayerNorm::reset_parameters(uint64_t, const std::string&) {
  if (!affine_) return;
  norm_affine_init(parameter("weight"), parameter("bias"));
}

Tensor LayerNorm::forward(const Tensor& x) {
  SL_CHECK(x.dim() >= 1 && x.size(-1) == features_, "LayerNorm(", features_, "): input ", x.describe(),
           " must end in ", features_);
  const Tensor centred = sub(x, mean(x, {-1}, true));
  const Tensor var = mean(square(centred), {-1}, true);
  Tensor y = div(centred, sqrt(add_scalar(var, eps_)));
  return affine_ ? add(mul(y, parameter("weight")), parameter("bias")) : y;
}

}  // namespace sl::nn
