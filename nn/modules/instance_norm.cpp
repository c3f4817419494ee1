#include "nn/modules/instance_norm.h"

#include "autodiff/tape.h"
#include "nn/functional/normalization.h"
#include "nn/init.h"
#include "nn/modules/activations.h"

namespace sl::nn {

InstanceNorm::InstanceNorm(int64_t channels, double eps, bool affine)
    : Module("InstanceNorm"), channels_(channels), eps_(eps), affine_(affine) {
  SL_CHECK(channels > 0 && eps > 0, "InstanceNorm: channels ", channels, " and eps ", eps, " must be > 0");
  if (affine) {
    register_parameter("weight", Tensor::ones({channels}));
    register_parameter("bias", Tensor::zeros({channels}));
  }
}

void InstanceNorm::reset_parameters(uint64_t, const std::string&) {
  if (affine_) norm_affine_init(parameter("weight"), parameter("bias"));
}

Tensor InstanceNorm::forward(const Tensor& x) {
  SL_CHECK(x.dim() >= 3 && x.size(1) == channels_, "InstanceNorm(", channels_, "): expected [N, ", channels_,
           ", spatial...], got ", x.describe());
  return instance_norm(x, affine_ ? parameter("weight") : Tensor(), affine_ ? parameter("bias") : Tensor(), eps_);
}

// ---------------------------------------------------------------- factory

}  // namespace sl::nn
