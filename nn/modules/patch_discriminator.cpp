#include "nn/modules/patch_discriminator.h"

#include <algorithm>

#include "nn/init.h"
#include "nn/layers.h"

namespace sl::nn {

PatchDiscriminator::PatchDiscriminator(PatchDiscriminatorOptions options)
    : Module("PatchDiscriminator"), opt_(std::move(options)) {
  SL_CHECK(opt_.in_channels > 0 && opt_.base_channels > 0 && opt_.layers >= 1 && opt_.layers <= 6,
           "PatchDiscriminator: in_channels ", opt_.in_channels, " and base_channels ", opt_.base_channels,
           " must be > 0 and layers ", opt_.layers, " in [1, 6]");
  const bool norm_bias = opt_.norm == "none";
  auto model = std::make_shared<Sequential>();
  const int64_t w = opt_.base_channels;
  model->push_back(std::make_shared<Conv2d>(opt_.in_channels, w, 4, ConvOptions{.stride = 2, .padding = 1}));
  model->push_back(std::make_shared<LeakyReLU>(0.2));
  int64_t prev = w;
  for (int n = 1; n <= opt_.layers; ++n) {
    const int64_t next = w * std::min<int64_t>(int64_t(1) << n, 8);
    const int64_t stride = n < opt_.layers ? 2 : 1;
    model->push_back(std::make_shared<Conv2d>(prev, next, 4, ConvOptions{.stride = stride, .padding = 1,
                                                                         .bias = norm_bias}));
    if (opt_.norm != "none") model->push_back(make_norm(opt_.norm, next, 2));
    model->push_back(std::make_shared<LeakyReLU>(0.2));
    prev = next;
  }
  model->push_back(std::make_shared<Conv2d>(prev, 1, 4, ConvOptions{.padding = 1}));
  model_ = register_module("model", model);
  init_parameters(opt_.seed);
}

void PatchDiscriminator::reset_parameters(uint64_t seed, const std::string& prefix) {
  for (auto& [name, m] : named_modules())
    if (dynamic_cast<Conv2d*>(m)) normal_init(m->parameter("weight"), 0.0, 0.02, seed, prefix + name + ".weight");
}

Tensor PatchDiscriminator::forward(const Tensor& x) {
  SL_CHECK(x.dim() == 4 && x.size(1) == opt_.in_channels, "PatchDiscriminator: expected [N, ", opt_.in_channels,
           ", H, W], got ", x.describe());
  return model_->forward(x);
}

}  // namespace sl::nn
