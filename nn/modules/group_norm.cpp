#include "nn/modules/group_norm.h"

#include "autodiff/tape.h"
#include "nn/functional/normalization.h"
#include "nn/init.h"
#include "nn/modules/activations.h"

namespace sl::nn {

GroupNorm::GroupNorm(int64_t groups, int64_t channels, double eps, bool affine)
    : Module("GroupNorm"), groups_(groups), channels_(channels), eps_(eps), affine_(affine) {
  SL_CHECK(groups > 0 && channels > 0 && channels % groups == 0 && eps > 0, "GroupNorm: ", channels,
           " channels must divide into ", groups, " groups (both > 0) and eps ", eps, " must be > 0");
  if (affine) {
    register_parameter("weight", Tensor::ones({channels}));
    register_parameter("bias", Tensor::zeros({channels}));
  }
}

void GroupNorm::reset_parameters(uint64_t, const std::string&) {
  if (affine_) norm_affine_init(parameter("weight"), parameter("bias"));
}

Tensor GroupNorm::forward(const Tensor& x) { return forward_activated(x, {}); }

Tensor GroupNorm::forward_absorbing(const Tensor& x, const Module& next) {
  const NormActivation act = fusable_activation(next);
  return act.kind == NormActivation::Kind::None ? Tensor() : forward_activated(x, act);
}

Tensor GroupNorm::forward_activated(const Tensor& x, NormActivation act) {
  SL_CHECK(x.dim() >= 2 && x.size(1) == channels_, "GroupNorm(", groups_, ", ", channels_, "): expected [N, ",
           channels_, ", ...], got ", x.describe());
  return group_norm(x, groups_, affine_ ? parameter("weight") : Tensor(), affine_ ? parameter("bias") : Tensor(),
                    eps_, act);
}

// ---------------------------------------------------------------- InstanceNorm

}  // namespace sl::nn
