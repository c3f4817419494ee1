#include "nn/modules/dropout.h"

#include "nn/functional/dropout.h"

namespace sl::nn {

Dropout::Dropout(double p, uint64_t seed) : Module("Dropout"), p_(p), seed_(seed) {
  SL_CHECK(p >= 0 && p < 1, "Dropout: p must lie in [0, 1), got ", p);
}

Tensor Dropout::forward(const Tensor& x) {
  if (!is_training() || p_ == 0) return x;
  return dropout(x, p_, true, seed_, step_++);
}

}  // namespace sl::nn
