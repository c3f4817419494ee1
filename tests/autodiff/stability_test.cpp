// Extreme inputs named by the foundation issue: no NaN or Inf where the math is finite.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "autodiff/ops.h"
#include "support/test_util.h"
#include "util/math.h"

namespace sl::test {
namespace {

using test::all_finite;

// y = op(x) for every dtype; returns y and dy/dx (for a ones upstream gradient).
std::pair<Tensor, Tensor> value_and_grad(const std::function<Tensor(const Tensor&)>& op, std::vector<double> xs,
                                         DType dt) {
  Tensor x = Tensor::from_vector(xs, {static_cast<int64_t>(xs.size())}, dt).set_requires_grad(true);
  Tensor y = op(x);
  backward(sum(y));
  return {y, x.grad()};
}

// leaky_relu and clamp convert their constants before selecting (so the loops vectorise): the
// result must still be exactly the textbook formula, signed zeros, infinities and NaN included.
TEST(Stability, LeakyReluAndClampGiveTheirFormulaOnSpecialValues) {
  const float inf = std::numeric_limits<float>::infinity(), nan = std::numeric_limits<float>::quiet_NaN();
  const std::vector<double> v = {-inf, -3.5, -1e-40, -0.0, 0.0, 1e-40, 0.25, 7.0, inf, nan};
  const Tensor x = Tensor::from_vector(v, {static_cast<int64_t>(v.size())}).set_requires_grad(true);
  const Tensor y = leaky_relu(x, 0.2), c = clamp(x, -1.0, 0.25);
  backward(add(sum(y), sum(c)));
  const std::vector<double> yv = y.to_vector(), cv = c.to_vector(), gv = x.grad().to_vector();
  for (size_t i = 0; i < v.size(); ++i) {
    const float f = static_cast<float>(v[i]);
    const float want_y = f > 0 ? f : 0.2f * f;
    const float want_c = f < -1.0f ? -1.0f : (f > 0.25f ? 0.25f : f);
    const float want_g = (f > 0 ? 1.0f : 0.2f) + ((f >= -1.0f && f <= 0.25f) ? 1.0f : 0.0f);
    if (std::isnan(f)) {
      EXPECT_TRUE(std::isnan(yv[i]) && std::isnan(cv[i]));
    } else {
      EXPECT_EQ(yv[i], want_y) << v[i];
      EXPECT_EQ(std::signbit(yv[i]), std::signbit(want_y)) << v[i];
      EXPECT_EQ(cv[i], want_c) << v[i];
    }
    EXPECT_EQ(gv[i], want_g) << v[i];
  }
}

TEST(Stability, SigmoidSoftplusAndLogsumexpAtPlusMinus1e4) {
  for (DType dt : {DType::F32, DType::F64}) {
    auto [s, ds] = value_and_grad([](const Tensor& x) { return sigmoid(x); }, {-1e4, -50, 0, 50, 1e4}, dt);
    EXPECT_TRUE(all_finite(s) && all_finite(ds));
    EXPECT_DOUBLE_EQ(s.at({0}), 0.0);
    EXPECT_DOUBLE_EQ(s.at({4}), 1.0);
    auto [p, dp] = value_and_grad([](const Tensor& x) { return softplus(x); }, {-1e4, 0, 1e4}, dt);
    EXPECT_TRUE(all_finite(p) && all_finite(dp));
    EXPECT_DOUBLE_EQ(p.at({0}), 0.0);
    EXPECT_DOUBLE_EQ(p.at({2}), 1e4);
    EXPECT_DOUBLE_EQ(dp.at({2}), 1.0);
    auto [l, dl] = value_and_grad([](const Tensor& x) { return logsumexp(x, 0); }, {1e4, -1e4, 1e4 - 1}, dt);
    EXPECT_TRUE(all_finite(l) && all_finite(dl));
    EXPECT_NEAR(l.item(), 1e4 + std::log1p(std::exp(-1.0)), dt == DType::F32 ? 1e-2 : 1e-9);
    auto [l2, dl2] = value_and_grad([](const Tensor& x) { return logsumexp(x, 0); }, {-1e4, -1e4}, dt);
    EXPECT_TRUE(all_finite(l2) && all_finite(dl2));
  }
}

TEST(Stability, LogsumexpOfAllMinusInfinityIsMinusInfinityWithZeroGradient) {
  const double inf = std::numeric_limits<double>::infinity();
  auto [l, dl] = value_and_grad([](const Tensor& x) { return logsumexp(x, 0); }, {-inf, -inf}, DType::F64);
  EXPECT_EQ(l.item(), -inf);
  EXPECT_TRUE(all_finite(dl));
}

TEST(Stability, Log1pAndExpNearHdrExtremes) {
  for (DType dt : {DType::F32, DType::F64}) {
    auto [y, dy] = value_and_grad([](const Tensor& x) { return log1p(x); }, {0, 1e-8, 1e6, 1e12}, dt);
    EXPECT_TRUE(all_finite(y) && all_finite(dy));
    EXPECT_NEAR(y.at({2}), std::log1p(1e6), 1e-4);
    // exp of log-radiance: a sun of 1e6 is exp(13.8); it must round-trip through log.
    auto [e, de] = value_and_grad([](const Tensor& x) { return exp(x); }, {std::log(1e6), std::log(1e-3), -100}, dt);
    EXPECT_TRUE(all_finite(e) && all_finite(de));
    EXPECT_NEAR(e.at({0}) / 1e6, 1.0, 1e-5);
    auto [m, dm] = value_and_grad([](const Tensor& x) { return expm1(x); }, {1e-10, std::log(1e6)}, dt);
    EXPECT_TRUE(all_finite(m) && all_finite(dm));
  }
}

TEST(Stability, NormalizeOfAZeroVectorIsZeroWithFiniteGradient) {
  for (DType dt : {DType::F32, DType::F64}) {
    Tensor x = Tensor::zeros({2, 3}, dt).set_requires_grad(true);
    Tensor y = normalize(x, 1);
    backward(sum(y));
    EXPECT_TRUE(all_finite(y));
    EXPECT_TRUE(all_finite(x.grad()));
    EXPECT_EQ(y.to_vector(), std::vector<double>(6, 0.0));
  }
}

TEST(Stability, AcosAtPlusMinusOneHasFiniteGradient) {
  for (DType dt : {DType::F32, DType::F64}) {
    auto [y, dy] = value_and_grad([](const Tensor& x) { return acos(x); }, {-1.0, 1.0, 1.0000001, -1.5}, dt);
    EXPECT_TRUE(all_finite(y) && all_finite(dy));
    EXPECT_NEAR(y.at({0}), kPi, 1e-6);
    EXPECT_DOUBLE_EQ(y.at({1}), 0.0);
    EXPECT_LT(dy.at({1}), 0.0);  // still points the right way
  }
}

TEST(Stability, PowWithAZeroBase) {
  for (DType dt : {DType::F32, DType::F64}) {
    for (double p : {0.0, 1.0, 2.0, 3.5}) {
      auto [y, dy] = value_and_grad([p](const Tensor& x) { return pow_scalar(x, p); }, {0.0, 2.0}, dt);
      EXPECT_TRUE(all_finite(y) && all_finite(dy)) << "p = " << p;
      EXPECT_DOUBLE_EQ(y.at({0}), p == 0.0 ? 1.0 : 0.0);
    }
    // Tensor exponent: d/db of 0^b uses log(0) only where the base is positive.
    Tensor a = Tensor::zeros({2}, dt).set_requires_grad(true);
    Tensor b = Tensor::from_vector({2.0, 0.0}, {2}, dt).set_requires_grad(true);
    backward(sum(pow(a, b)));
    EXPECT_TRUE(all_finite(a.grad()) && all_finite(b.grad()));
  }
}

TEST(Stability, Atan2AtTheOriginHasZeroGradient) {
  Tensor y = Tensor::zeros({1}, DType::F64).set_requires_grad(true);
  Tensor x = Tensor::zeros({1}, DType::F64).set_requires_grad(true);
  backward(sum(atan2(y, x)));
  EXPECT_TRUE(all_finite(y.grad()) && all_finite(x.grad()));
}

TEST(Stability, HdrSumsAccumulateInDouble) {
  // A sun of 1e6 in one texel beside a million texels of 1e-3: float accumulation would drop
  // the sky entirely; the fixed-block double accumulation keeps it.
  Tensor t = Tensor::full({1 << 20}, 1e-3f, DType::F32);
  t.data<float>()[12345] = 1e6f;
  const double s = sum(t).item();
  EXPECT_NEAR(s, 1e6 + 1e-3 * ((1 << 20) - 1), 1.0);
}

TEST(Stability, GridSampleIgnoresNonFiniteCoordinates) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  Tensor img = Tensor::ones({1, 1, 2, 2}, DType::F64).set_requires_grad(true);
  Tensor grid = Tensor::from_vector({nan, 0.0, 0.0, 0.0}, {1, 1, 2, 2}, DType::F64).set_requires_grad(true);
  Tensor y = grid_sample_2d(img, grid);
  backward(sum(y));
  EXPECT_TRUE(all_finite(y) && all_finite(img.grad()) && all_finite(grid.grad()));
  EXPECT_DOUBLE_EQ(y.at({0, 0, 0, 0}), 0.0);
}

}  // namespace
}  // namespace sl::test
