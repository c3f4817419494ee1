// LayerNorm over the last dimension, as torch.nn.LayerNorm(features).
//
// Contract: x [..., features] -> (x − mean) / sqrt(var + eps) · weight + bias, with mean and the
// biased variance over the last dim. Parameters `weight` (ones) and `bias` (zeros) [features]
// when affine. Composed of autodiff ops, so its gradient is theirs. Throws naming the layer
// when the last dim differs from `features`.
#pragma once
#include "nn/module.h"

namespace sl::nn {

class LayerNorm : public Module {
 public:
  explicit LayerNorm(int64_t features, double eps = 1e-5, bool affine = true);
  Tensor forward(const Tensor& x) override;

 protected:
  void reset_parameters(uint64_t seed, const std::string& prefix) override;

 private:
  int64_t features_;
  double eps_;
  bool affine_;
};

}  // namespace sl::nn
