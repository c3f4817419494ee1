// gradcheck: analytic gradients against float64 central finite differences.
//
// Contract: fn maps the inputs to one output tensor; inputs must be F64 leaves (gradcheck marks
// them requires_grad). The scalar checked is L = Σ w ⊙ fn(inputs) with a fixed pseudo-random
// weight w in [0.5, 1.5], so every output element and its position matter. Each input element
// x is perturbed in place by ±eps and ∂L/∂x ≈ (L(x+eps) − L(x−eps)) / 2eps is compared with
// backward(): |analytic − numeric| <= atol + rtol·|numeric| must hold for every element.
// The returned result says which input and element failed first, and by how much.
//
// The tolerances live here and only here: they suit smooth f64 functions with O(1) inputs;
// keep gradcheck inputs away from kinks (relu at 0, clamp bounds, ties in max) by more than eps.
#pragma once
#include <functional>
#include <string>

#include "autodiff/tape.h"

namespace sl {

struct GradcheckTolerance {
  static constexpr double kEps = 1e-6;
  static constexpr double kAtol = 1e-5;
  static constexpr double kRtol = 1e-3;
};

struct GradcheckResult {
  bool ok = true;
  double max_abs_error = 0.0;
  std::string message;  // empty when ok
};

GradcheckResult gradcheck(const std::function<Tensor(const TensorList&)>& fn, TensorList inputs,
                          double eps = GradcheckTolerance::kEps, double atol = GradcheckTolerance::kAtol,
                          double rtol = GradcheckTolerance::kRtol);

}  // namespace sl
