#include "nn/layers_norm.h"

#include "autodiff/tape.h"
#include "nn/activations.h"
#include "nn/normalization.h"

namespace sl::nn {

namespace {
void reset_affine(Module& m, bool affine) {
  if (!affine) return;
  m.parameter("weight").fill_(1.0);
  m.parameter("bias").fill_(0.0);
}
}  // namespace

// ---------------------------------------------------------------- BatchNorm
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

void BatchNormNd::reset_parameters(uint64_t, const std::string&) { reset_affine(*this, affine_); }

Tensor BatchNormNd::forward(const Tensor& x) {
  const bool rank_ok = dims_ == 1 ? (x.dim() == 2 || x.dim() == 3) : x.dim() == dims_ + 2;
  SL_CHECK(rank_ok && x.size(1) == features_, type_name(), "(", features_, "): expected input [N, ", features_,
           dims_ == 1 ? "] or [N, C, L]" : (dims_ == 2 ? ", H, W]" : ", D, H, W]"), ", got ", x.describe());
  const Tensor w = affine_ ? parameter("weight") : Tensor();
  const Tensor b = affine_ ? parameter("bias") : Tensor();
  if (!track_) return batch_norm(x, Tensor(), Tensor(), w, b, true, momentum_, eps_);
  const bool training = is_training();
  Tensor y = batch_norm(x, buffer("running_mean"), buffer("running_var"), w, b, training, momentum_, eps_);
  if (training) buffer("num_batches_tracked").data<int64_t>()[0] += 1;
  return y;
}

// ---------------------------------------------------------------- GroupNorm
GroupNorm::GroupNorm(int64_t groups, int64_t channels, double eps, bool affine)
    : Module("GroupNorm"), groups_(groups), channels_(channels), eps_(eps), affine_(affine) {
  SL_CHECK(groups > 0 && channels > 0 && channels % groups == 0 && eps > 0, "GroupNorm: ", channels,
           " channels must divide into ", groups, " groups (both > 0) and eps ", eps, " must be > 0");
  if (affine) {
    register_parameter("weight", Tensor::ones({channels}));
    register_parameter("bias", Tensor::zeros({channels}));
  }
}

void GroupNorm::reset_parameters(uint64_t, const std::string&) { reset_affine(*this, affine_); }

Tensor GroupNorm::forward(const Tensor& x) {
  SL_CHECK(x.dim() >= 2 && x.size(1) == channels_, "GroupNorm(", groups_, ", ", channels_, "): expected [N, ",
           channels_, ", ...], got ", x.describe());
  return group_norm(x, groups_, affine_ ? parameter("weight") : Tensor(), affine_ ? parameter("bias") : Tensor(),
                    eps_);
}

// ---------------------------------------------------------------- InstanceNorm
InstanceNorm::InstanceNorm(int64_t channels, double eps, bool affine)
    : Module("InstanceNorm"), channels_(channels), eps_(eps), affine_(affine) {
  SL_CHECK(channels > 0 && eps > 0, "InstanceNorm: channels ", channels, " and eps ", eps, " must be > 0");
  if (affine) {
    register_parameter("weight", Tensor::ones({channels}));
    register_parameter("bias", Tensor::zeros({channels}));
  }
}

void InstanceNorm::reset_parameters(uint64_t, const std::string&) { reset_affine(*this, affine_); }

Tensor InstanceNorm::forward(const Tensor& x) {
  SL_CHECK(x.dim() >= 3 && x.size(1) == channels_, "InstanceNorm(", channels_, "): expected [N, ", channels_,
           ", spatial...], got ", x.describe());
  return instance_norm(x, affine_ ? parameter("weight") : Tensor(), affine_ ? parameter("bias") : Tensor(), eps_);
}

// ---------------------------------------------------------------- factory
std::shared_ptr<Module> make_norm(const std::string& kind, int64_t channels, int spatial_dims, int64_t groups) {
  SL_CHECK(spatial_dims >= 1 && spatial_dims <= 3, "make_norm: spatial_dims must be 1, 2 or 3, got ", spatial_dims);
  if (kind == "batch") {
    if (spatial_dims == 1) return std::make_shared<BatchNorm1d>(channels);
    if (spatial_dims == 2) return std::make_shared<BatchNorm2d>(channels);
    return std::make_shared<BatchNorm3d>(channels);
  }
  if (kind == "group") {
    SL_CHECK(groups >= 1, "make_norm: groups must be >= 1, got ", groups);
    int64_t g = std::min(groups, channels);
    while (channels % g != 0) --g;
    return std::make_shared<GroupNorm>(g, channels);
  }
  if (kind == "instance") return std::make_shared<InstanceNorm>(channels, 1e-5, true);
  if (kind == "none") return std::make_shared<Identity>();
  fail("make_norm: unknown norm '", kind, "' (valid: batch, group, instance, none)");
}

}  // namespace sl::nn
