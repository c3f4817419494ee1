// Dropout module over nn/functional/dropout.h, with a seeded, counter-based mask.
//
// Contract: Dropout(p, seed) drops each element with probability p in training (scaling the
// rest by 1/(1-p)) and is the identity in eval. The mask of the k-th training forward call is
// a pure function of (seed, k, element index): runs with the same seed replay the same masks,
// whatever the thread count. step() is k (not a buffer, so state dicts stay PyTorch-compatible).
// 0 <= p < 1, else sl::Error.
#pragma once
#include "nn/module.h"

namespace sl::nn {

class Dropout : public Module {
 public:
  explicit Dropout(double p = 0.5, uint64_t seed = 0);
  Tensor forward(const Tensor& x) override;
  uint64_t step() const { return step_; }

 private:
  double p_;
  uint64_t seed_;
  uint64_t step_ = 0;
};

}  // namespace sl::nn
