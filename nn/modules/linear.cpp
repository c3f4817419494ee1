#include "nn/modules/linear.h"

#include "autodiff/ops.h"
#include "nn/functional/linear.h"
#include "nn/init.h"

namespace sl::nn {

Linear::Linear(int64_t in_features, int64_t out_features, bool bias)
    : Module("Linear"), in_(in_features), out_(out_features), has_bias_(bias) {
  SL_CHECK(in_features > 0 && out_features > 0, "Linear: features must be positive, got in=", in_features,
           " out=", out_features);
  register_parameter("weight", Tensor::empty({out_features, in_features}));
  if (bias) register_parameter("bias", Tensor::empty({out_features}));
  reset_parameters(0, "");
}

void Linear::reset_parameters(uint64_t seed, const std::string& prefix) {
  Tensor none;
  default_layer_init(parameter("weight"), has_bias_ ? parameter("bias") : none, seed, prefix);
}

Tensor Linear::forward(const Tensor& x) {
  SL_CHECK(x.dim() >= 1 && x.size(-1) == in_, "Linear(", in_, " -> ", out_, "): input ", x.describe(),
           " must end in ", in_);
  return linear(x, parameter("weight"), has_bias_ ? parameter("bias") : Tensor());
}

}  // namespace sl::nn
