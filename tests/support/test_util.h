// Helpers shared by the tests: float64 random tensors, finiteness, |·| sums, gradcheck.
#pragma once
#include <gtest/gtest.h>

#include <cmath>

#include "autodiff/gradcheck.h"
#include "autodiff/ops.h"

namespace sl::test {

inline Tensor rand64(const Shape& shape, uint64_t seed, double lo = -1.0, double hi = 1.0) {
  return Tensor::uniform(shape, lo, hi, seed, DType::F64);
}

inline bool all_finite(const Tensor& t) {
  if (!t.defined()) return true;
  for (double v : t.to_vector())
    if (!std::isfinite(v)) return false;
  return true;
}

inline double abs_sum(const Tensor& t) {
  double s = 0;
  for (double v : t.to_vector()) s += std::abs(v);
  return s;
}

#define EXPECT_GRADCHECK(fn, ...)                                       \
  do {                                                                  \
    const ::sl::GradcheckResult _r = ::sl::gradcheck(fn, __VA_ARGS__);  \
    EXPECT_TRUE(_r.ok) << _r.message;                                   \
  } while (0)

}  // namespace sl::test
