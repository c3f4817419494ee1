// PatchGAN discriminator (pix2pix's NLayerDiscriminator): a convolutional critic whose output
// is a 1-channel map, one logit per overlapping image patch.
//
// Contract:
// - Layers (all 4×4 convs, padding 1), in one Sequential named "model":
//   conv(in → w, stride 2) → LeakyReLU(0.2);
//   for n = 1..layers−1: conv(→ w·min(2^n, 8), stride 2) → norm → LeakyReLU(0.2);
//   conv(→ w·min(2^layers, 8), stride 1) → norm → LeakyReLU(0.2); conv(→ 1, stride 1).
//   Parameter names: model.0.weight, model.2.weight, model.3.weight (norm), ...
// - norm: "batch", "instance", "group" or "none"; convs followed by a norm have no bias.
// - forward(x [N, in, H, W]) -> logits [N, 1, H', W'] (no sigmoid: pair with a logit loss).
//   The input must be large enough for every conv (at least 2^(layers+2) per side is safe);
//   otherwise the conv op throws naming the shapes.
// - Weights ~ N(0, 0.02) as pix2pix, seeded by name; norms weight 1, bias 0.
#pragma once
#include <memory>
#include <string>

#include "nn/module.h"

namespace sl::nn {

struct PatchDiscriminatorOptions {
  int64_t in_channels = 3;
  int64_t base_channels = 64;
  int layers = 3;
  std::string norm = "batch";
  uint64_t seed = 0;
};

class PatchDiscriminator : public Module {
 public:
  explicit PatchDiscriminator(PatchDiscriminatorOptions options);
  Tensor forward(const Tensor& x) override;
  const PatchDiscriminatorOptions& options() const { return opt_; }

 protected:
  void reset_parameters(uint64_t seed, const std::string& prefix) override;

 private:
  PatchDiscriminatorOptions opt_;
  std::shared_ptr<Module> model_;
};

}  // namespace sl::nn
