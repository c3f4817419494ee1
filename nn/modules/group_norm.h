// GroupNorm, as torch.nn.GroupNorm.
//
// Contract:
// - GroupNorm(groups, channels): `weight`/`bias` [C] when affine; C must divide by groups.
#pragma once
#include <string>

#include "nn/functional/normalization.h"
#include "nn/module.h"

namespace sl::nn {

class GroupNorm : public Module {
 public:
  GroupNorm(int64_t groups, int64_t channels, double eps = 1e-5, bool affine = true);
  Tensor forward(const Tensor& x) override;
  // act(forward(x)) as one op (nn/functional/normalization.h).
  Tensor forward_activated(const Tensor& x, NormActivation act);
  Tensor forward_absorbing(const Tensor& x, const Module& next) override;

 protected:
  void reset_parameters(uint64_t seed, const std::string& prefix) override;

 private:
  int64_t groups_, channels_;
  double eps_;
  bool affine_;
};

}  // namespace sl::nn
