// Elementwise unary ops, each with its backward beside it in unary.cpp.
//
// Contract: floating tensors of any shape and strides in; a contiguous tensor of the same shape
// and dtype out. Stability conventions (tested in tests/autodiff/stability_test.cpp):
//   sigmoid, softplus: overflow-free for any finite input (|x| up to 1e4 and beyond);
//     softplus(x) = max(x, 0) + log1p(exp(-|x|)).
//   acos: the input is clamped to [-1, 1]; the derivative's 1 - x² is floored at
//     kAcosGradFloor (1e-6 in f32, 1e-12 in f64), so acos at ±1 has a large finite gradient.
//   pow_scalar(x, p): the derivative is exactly 0 where p == 0, and p·x^(p-1) elsewhere
//     (0 at x = 0 for p > 1).
//   abs, relu, clamp: subgradient 0 at the kink for abs and relu; clamp passes the gradient
//     where lo <= x <= hi (inclusive, as PyTorch).
//   log, sqrt: faithful (log 0 = -inf): use log_eps / a floor where inputs can reach 0.
#pragma once
#include "autodiff/tensor.h"

namespace sl {

Tensor neg(const Tensor& x);
Tensor exp(const Tensor& x);
Tensor log(const Tensor& x);
Tensor log1p(const Tensor& x);
Tensor expm1(const Tensor& x);
Tensor sqrt(const Tensor& x);
Tensor square(const Tensor& x);
Tensor abs(const Tensor& x);
Tensor pow_scalar(const Tensor& x, double p);
Tensor clamp(const Tensor& x, double lo, double hi);
Tensor relu(const Tensor& x);
Tensor leaky_relu(const Tensor& x, double negative_slope = 0.01);
Tensor elu(const Tensor& x, double alpha = 1.0);
Tensor sigmoid(const Tensor& x);
Tensor softplus(const Tensor& x);
Tensor tanh(const Tensor& x);
Tensor sin(const Tensor& x);
Tensor cos(const Tensor& x);
Tensor acos(const Tensor& x);

}  // namespace sl
