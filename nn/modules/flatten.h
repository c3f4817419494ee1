// The Flatten module.
//
// Contract:
// - Flatten(start_dim = 1): x [N, ...] -> [N, Π...] as torch.nn.Flatten; no parameters.
// - Throws sl::Error naming the module and the input's shape when x has start_dim dims or fewer.
#pragma once
#include "nn/module.h"

namespace sl::nn {

class Flatten : public Module {
 public:
  explicit Flatten(int64_t start_dim = 1) : Module("Flatten"), start_dim_(start_dim) {}
  Tensor forward(const Tensor& x) override;

 private:
  int64_t start_dim_;
};

}  // namespace sl::nn
