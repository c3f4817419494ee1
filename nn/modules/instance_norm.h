// InstanceNorm, as torch.nn.InstanceNorm2d/3d.
//
// Contract:
// - InstanceNorm(channels, affine = false): as torch.nn.InstanceNorm2d/3d without running
//   statistics; `weight`/`bias` [C] only when affine. Any rank >= 3.
#pragma once
#include <string>

#include "nn/module.h"

namespace sl::nn {

class InstanceNorm : public Module {
 public:
  explicit InstanceNorm(int64_t channels, double eps = 1e-5, bool affine = false);
  Tensor forward(const Tensor& x) override;

 protected:
  void reset_parameters(uint64_t seed, const std::string& prefix) override;

 private:
  int64_t channels_;
  double eps_;
  bool affine_;
};

}  // namespace sl::nn
