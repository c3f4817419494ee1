#include "nn/functional/gradient_reversal.h"

#include <cmath>

#include "autodiff/ops.h"
#include "autodiff/tape.h"

namespace sl::nn {

Tensor gradient_reversal(const Tensor& x, double lambda) {
  SL_CHECK(x.defined(), "gradient_reversal: input is undefined");
  SL_CHECK(x.dtype() != DType::I64, "gradient_reversal: expected a floating tensor, got ", x.describe());
  SL_CHECK(std::isfinite(lambda), "gradient_reversal: lambda must be finite, got ", lambda);
  const Tensor y = x.detach().contiguous().clone();
  if (needs_grad({x}))
    record("gradient_reversal", {x}, {y}, [lambda](const TensorList& grads) {
      NoGradGuard no_grad;
      return TensorList{mul_scalar(grads[0], -lambda)};
    });
  return y;
}

}  // namespace sl::nn
