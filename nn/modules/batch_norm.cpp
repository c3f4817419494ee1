#include "nn/modules/batch_norm.h"

#include "autodiff/ops.h"
#include "autodiff/tape.h"
#include "nn/functional/normalization.h"
#include "nn/init.h"
#include "nn/modules/activations.h"

namespace sl::nn {

BatchNormNd::BatchNormNd(const char* type_name, int spatial_dims, int64_t features, double eps, double momentum,
                         bool affine, bool track_running_stats)
    : Module(type_name), dims_(spatial_dims), features_(features), eps_(eps), momentum_(momentum),
      affine_(affine), track_(track_running_stats) {
  SL_CHECK(features > 0 && eps > 0 && momentum >= 0 && momentum <= 1, type_name, ": features ", features,
           " and eps ", eps, " must be > 0 and momentum ", momentum, " in [0, 1]");
  if (affine) {
    register_parameter("weight", Tensor::ones({features}));
    register_parameter("bias", Tensor::zeros({features}));
  }
  if (track_running_stats) {
    register_buffer("running_mean", Tensor::zeros({features}));
    register_buffer("running_var", Tensor::ones({features}));
    register_buffer("num_batches_tracked", Tensor::zeros({}, DType::I64));
  }
}

void BatchNormNd::reset_parameters(uint64_t, const std::string&) {
  if (affine_) norm_affine_init(parameter("weight"), parameter("bias"));
}

Tensor BatchNormNd::forward(const Tensor& x) { return forward_activated(x, {}); }

Tensor BatchNormNd::forward_absorbing(const Tensor& x, const Module& next) {
  const NormActivation act = fusable_activation(next);
  return act.kind == NormActivation::Kind::None ? Tensor() : forward_activated(x, act);
}

Tensor BatchNormNd::forward_activated(const Tensor& x, NormActivation act) {
  const bool rank_ok = dims_ == 1 ? (x.dim() == 2 || x.dim() == 3) : x.dim() == dims_ + 2;
  SL_CHECK(rank_ok && x.size(1) == features_, type_name(), "(", features_, "): expected input [N, ", features_,
           dims_ == 1 ? "] or [N, C, L]" : (dims_ == 2 ? ", H, W]" : ", D, H, W]"), ", got ", x.describe());
  if (folded_) {
    SL_CHECK(!is_training(), type_name(), "(", features_, ") is folded into its conv (inference only): training mode is refused");
    switch (act.kind) {
      case NormActivation::Kind::ReLU: return relu(x);
      case NormActivation::Kind::LeakyReLU: return leaky_relu(x, act.slope);
      case NormActivation::Kind::None: return x;
    }
  }
  const Tensor w = affine_ ? parameter("weight") : Tensor();
  const Tensor b = affine_ ? parameter("bias") : Tensor();
  if (!track_) return batch_norm(x, Tensor(), Tensor(), w, b, true, momentum_, eps_, act);
  const bool training = is_training();
  Tensor y = batch_norm(x, buffer("running_mean"), buffer("running_var"), w, b, training, momentum_, eps_, act);
  if (training) buffer("num_batches_tracked").data<int64_t>()[0] += 1;
  return y;
}

// ---------------------------------------------------------------- GroupNorm

}  // namespace sl::nn
