// Accuracy and agreement of the vectorised transcendental functions (autodiff/vector_math.h).
//
// The sweep covers every 251st float bit pattern of both signs (17M inputs; the prime stride
// varies the low mantissa bits; zeros, denormals, normals, ±inf and NaNs included) plus named special values, compares each result with float64
// libm, and asserts the ulp bound stated in vector_math.h. Every SIMD level the CPU has must give
// the same bits as the scalar fallback.
#include "autodiff/vector_math.h"

#include <gtest/gtest.h>

#include "autodiff/ops.h"

#include <cmath>
#include <cstdint>
#include <cstring>
#include <functional>
#include <limits>
#include <vector>

namespace sl::test {
using vm::SimdLevel;
using vm::active_simd_level;
using vm::cpu_simd_level;
using vm::force_simd_level;
using vm::kMaxUlpExp;
using vm::kMaxUlpLog;
using vm::kMaxUlpPow;
using vm::kMaxUlpSigmoid;
using vm::kMaxUlpSoftplus;
using vm::kMaxUlpTanh;
using vm::simd_level_name;

namespace {

float from_bits(uint32_t b) {
  float f;
  std::memcpy(&f, &b, 4);
  return f;
}
uint32_t to_bits(float f) {
  uint32_t b;
  std::memcpy(&b, &f, 4);
  return b;
}

std::vector<float> sweep_inputs(uint32_t kStride = 251) {
  std::vector<float> xs;
  xs.reserve((uint64_t{1} << 32) / kStride + 64);
  for (uint64_t b = 0; b < (uint64_t{1} << 32); b += kStride) xs.push_back(from_bits(static_cast<uint32_t>(b)));
  const float inf = std::numeric_limits<float>::infinity();
  for (float v : {0.0f, -0.0f, inf, -inf, std::numeric_limits<float>::quiet_NaN(), 1.0f, -1.0f,
                  std::numeric_limits<float>::denorm_min(), -std::numeric_limits<float>::denorm_min(),
                  std::numeric_limits<float>::min(), std::numeric_limits<float>::max(),
                  -std::numeric_limits<float>::max(), 88.7228394f, 88.7228317f, -87.3365479f, -103.972084f,
                  -103.9f, 0.549306f, 0.549307f, 9.01f, 1.0e-30f, 0.5f, 2.0f, 0.999999f, 1.000001f})
    xs.push_back(v);
  return xs;
}

// ulp error of a float result against a double reference, in units of the float spacing at the
// reference (the denormal spacing below FLT_MIN). Both NaN, or the same infinity, is 0.
double ulp_error(float got, double ref) {
  if (std::isnan(ref) || std::isnan(got)) return std::isnan(ref) && std::isnan(got) ? 0.0 : 1e30;
  if (std::isinf(ref) || std::isinf(got)) {
    if (got == ref) return 0.0;
    // Results that round to the largest float overflow only past FLT_MAX + half an ulp.
    if (std::isinf(got) && std::fabs(ref) > 3.4028235677973366e38) return 0.0;
    return 1e30;
  }
  const double a = std::fabs(ref);
  const int e = a < 1.1754943508222875e-38 ? -126 : std::ilogb(a);
  const double spacing = std::ldexp(1.0, std::max(e, -126) - 23);
  return std::fabs(static_cast<double>(got) - ref) / spacing;
}

struct Worst {
  double ulp = 0;
  float x = 0;
};

Worst check(const std::vector<float>& xs, const std::function<void(const float*, float*, int64_t)>& f,
            const std::function<double(double)>& ref) {
  std::vector<float> y(xs.size());
  f(xs.data(), y.data(), static_cast<int64_t>(xs.size()));
  Worst w;
  for (size_t i = 0; i < xs.size(); ++i) {
    const double e = ulp_error(y[i], ref(static_cast<double>(xs[i])));
    if (e > w.ulp) w = {e, xs[i]};
  }
  return w;
}

double sigmoid_ref(double x) { return x >= 0 ? 1.0 / (1.0 + std::exp(-x)) : std::exp(x) / (1.0 + std::exp(x)); }
double softplus_ref(double x) { return std::max(x, 0.0) + std::log1p(std::exp(-std::fabs(x))); }

class VectorMathAccuracy : public ::testing::Test {
 protected:
  static void SetUpTestSuite() { xs_ = new std::vector<float>(sweep_inputs()); }
  static void TearDownTestSuite() { delete xs_; }
  static std::vector<float>* xs_;
};
std::vector<float>* VectorMathAccuracy::xs_ = nullptr;

#define SL_EXPECT_ULP(name, fn, ref, bound)                                                   \
  do {                                                                                        \
    const Worst w = check(*xs_, fn, ref);                                                     \
    EXPECT_LE(w.ulp, bound) << name << " worst at x = " << w.x << " (bits 0x" << std::hex     \
                            << to_bits(w.x) << ")";                                           \
    std::printf("%-9s max error %.3f ulp (at %.9g) [%s]\n", name, w.ulp, w.x,                 \
                simd_level_name(active_simd_level()));                                        \
  } while (0)

TEST_F(VectorMathAccuracy, ExpWithinStatedUlpOverAllFloats) {
  SL_EXPECT_ULP("exp", vm::exp, [](double x) { return std::exp(x); }, kMaxUlpExp);
}
TEST_F(VectorMathAccuracy, LogWithinStatedUlpOverAllFloats) {
  SL_EXPECT_ULP("log", vm::log, [](double x) { return std::log(x); }, kMaxUlpLog);
}
TEST_F(VectorMathAccuracy, TanhWithinStatedUlpOverAllFloats) {
  SL_EXPECT_ULP("tanh", vm::tanh, [](double x) { return std::tanh(x); }, kMaxUlpTanh);
}
TEST_F(VectorMathAccuracy, SigmoidWithinStatedUlpOverAllFloats) {
  SL_EXPECT_ULP("sigmoid", vm::sigmoid, sigmoid_ref, kMaxUlpSigmoid);
}
TEST_F(VectorMathAccuracy, SoftplusWithinStatedUlpOverAllFloats) {
  SL_EXPECT_ULP("softplus", vm::softplus, softplus_ref, kMaxUlpSoftplus);
}
TEST_F(VectorMathAccuracy, PowWithinStatedUlpForManyExponents) {
  const std::vector<float> xs = sweep_inputs(2039);  // 2.1M inputs per exponent
  for (float p : {2.0f, 3.0f, -1.0f, -2.0f, 0.5f, -0.5f, 1.0f / 2.2f, 2.2f, 7.0f, -3.0f, 1e-3f, 40.5f}) {
    const Worst w = check(xs, [p](const float* x, float* y, int64_t n) { vm::pow(x, p, y, n); },
                          [p](double x) { return std::pow(x, static_cast<double>(p)); });
    EXPECT_LE(w.ulp, kMaxUlpPow) << "pow(x, " << p << ") worst at x = " << w.x;
    std::printf("pow(x, %g) max error %.3f ulp (at %.9g)\n", p, w.ulp, w.x);
  }
}

TEST(VectorMath, SpecialValuesFollowCAnnexF) {
  const float inf = std::numeric_limits<float>::infinity(), nan = std::numeric_limits<float>::quiet_NaN();
  const std::vector<float> x{-inf, -0.0f, 0.0f, inf, nan, 100.0f, -200.0f};
  std::vector<float> y(x.size());
  vm::exp(x.data(), y.data(), 7);
  EXPECT_EQ(y[0], 0.0f);
  EXPECT_EQ(y[1], 1.0f);
  EXPECT_EQ(y[3], inf);
  EXPECT_TRUE(std::isnan(y[4]));
  EXPECT_EQ(y[5], inf);
  EXPECT_EQ(y[6], 0.0f);
  vm::log(x.data(), y.data(), 7);
  EXPECT_TRUE(std::isnan(y[0]));
  EXPECT_EQ(y[1], -inf);
  EXPECT_EQ(y[2], -inf);
  EXPECT_EQ(y[3], inf);
  EXPECT_TRUE(std::isnan(y[4]));
  EXPECT_TRUE(std::isnan(y[6]));
  vm::tanh(x.data(), y.data(), 7);
  EXPECT_EQ(y[0], -1.0f);
  EXPECT_TRUE(std::signbit(y[1]) && y[1] == 0.0f);
  EXPECT_EQ(y[3], 1.0f);
  EXPECT_TRUE(std::isnan(y[4]));
  vm::sigmoid(x.data(), y.data(), 7);
  EXPECT_EQ(y[0], 0.0f);
  EXPECT_EQ(y[2], 0.5f);
  EXPECT_EQ(y[3], 1.0f);
  EXPECT_TRUE(std::isnan(y[4]));
  vm::softplus(x.data(), y.data(), 7);
  EXPECT_EQ(y[0], 0.0f);
  EXPECT_EQ(y[3], inf);
  EXPECT_TRUE(std::isnan(y[4]));
  EXPECT_EQ(y[5], 100.0f);
  // pow: negative bases with integer exponents, signed zeros, infinities.
  const std::vector<float> b{-2.0f, -0.0f, 0.0f, -inf, -1.5f, inf};
  std::vector<float> r(b.size());
  vm::pow(b.data(), 3.0f, r.data(), 6);
  EXPECT_EQ(r[0], -8.0f);
  EXPECT_TRUE(std::signbit(r[1]) && r[1] == 0.0f);
  EXPECT_EQ(r[3], -inf);
  EXPECT_EQ(r[5], inf);
  vm::pow(b.data(), -1.0f, r.data(), 6);
  EXPECT_EQ(r[1], -inf);
  EXPECT_EQ(r[2], inf);
  EXPECT_EQ(r[3], -0.0f);
  vm::pow(b.data(), 0.5f, r.data(), 6);
  EXPECT_TRUE(std::isnan(r[0]));
  EXPECT_EQ(r[3], inf);
  EXPECT_TRUE(std::isnan(r[4]));
  vm::pow(b.data(), 0.0f, r.data(), 6);
  for (float v : r) EXPECT_EQ(v, 1.0f);
}

// Every level the CPU supports gives the scalar fallback's bits, for every length (tails).
TEST(VectorMath, EverySimdLevelMatchesScalarBitwise) {
  std::vector<float> xs = sweep_inputs();
  xs.resize(1 << 22);  // a spread over the range is enough here
  for (size_t i = 0; i < xs.size(); ++i) xs[i] = from_bits(static_cast<uint32_t>(i * 1023u + 17u));
  const SimdLevel saved = active_simd_level();
  using Fn = std::function<void(const float*, float*, int64_t)>;
  const std::vector<std::pair<const char*, Fn>> fns{
      {"exp", vm::exp}, {"log", vm::log}, {"tanh", vm::tanh}, {"sigmoid", vm::sigmoid}, {"softplus", vm::softplus},
      {"pow", [](const float* x, float* y, int64_t n) { vm::pow(x, 2.2f, y, n); }},
      {"softplus_backward", [](const float* x, float* y, int64_t n) { vm::softplus_backward(x, x, y, n); }}};
  for (const auto& [name, f] : fns) {
    force_simd_level(SimdLevel::Scalar);
    std::vector<float> want(xs.size());
    f(xs.data(), want.data(), static_cast<int64_t>(xs.size()));
    for (SimdLevel level : {SimdLevel::Avx2, SimdLevel::Avx512}) {
      if (static_cast<int>(level) > static_cast<int>(cpu_simd_level())) continue;
      force_simd_level(level);
      for (int64_t n : {int64_t(xs.size()), int64_t(37), int64_t(5)}) {
        std::vector<float> got(static_cast<size_t>(n));
        f(xs.data(), got.data(), n);
        for (int64_t i = 0; i < n; ++i)  // NaN payloads may differ; NaN-ness may not
          ASSERT_TRUE(to_bits(got[i]) == to_bits(want[i]) || (std::isnan(got[i]) && std::isnan(want[i])))
              << name << " at " << simd_level_name(level) << " x = " << xs[i] << " n = " << n;
      }
    }
  }
  force_simd_level(saved);
}

// vm::sum: every level gives the scalar fallback's bits for lengths around the 32-wide body and
// its tail, and the sum is within the double-accumulation bound of the exact (long double) one:
// |error| ≤ (n/32 + 5 + n mod 32)·ε_double·Σ|x| (each partial sum adds at most n/32 terms, the
// pairwise combine 5 levels, the tail one add per element).
TEST(VectorMath, SumMatchesScalarBitwiseAndTheExactSum) {
  std::vector<float> xs(100003);
  for (size_t i = 0; i < xs.size(); ++i) xs[i] = float(std::sin(0.37 * double(i)) * std::exp(double(i % 97) / 10.0));
  const SimdLevel saved = active_simd_level();
  for (int64_t n : {int64_t(0), int64_t(1), int64_t(31), int64_t(32), int64_t(33), int64_t(4096), int64_t(100003)}) {
    force_simd_level(SimdLevel::Scalar);
    const double want = vm::sum(xs.data(), n);
    long double exact = 0, magnitude = 0;
    for (int64_t i = 0; i < n; ++i) exact += xs[size_t(i)], magnitude += std::fabs(xs[size_t(i)]);
    const double bound = double(n / 32 + 5 + n % 32) * 2.220446049250313e-16 * double(magnitude);
    EXPECT_LE(std::fabs(double(exact) - want), bound) << "n = " << n;
    for (SimdLevel level : {SimdLevel::Avx2, SimdLevel::Avx512}) {
      if (static_cast<int>(level) > static_cast<int>(cpu_simd_level())) continue;
      force_simd_level(level);
      const double got = vm::sum(xs.data(), n);
      EXPECT_EQ(std::memcmp(&got, &want, sizeof got), 0) << simd_level_name(level) << " n = " << n << ": " << got
                                                         << " vs " << want;
    }
  }
  force_simd_level(saved);
}

// The float32 tensor ops (vectorised path, several parallel chunks) and their gradients agree
// with the float64 ops (libm path) to float precision.
TEST(VectorMath, Float32TensorOpsAndGradientsMatchFloat64) {
  using TensorFn = std::function<Tensor(const Tensor&)>;
  const std::vector<std::pair<const char*, TensorFn>> ops{
      {"exp", [](const Tensor& x) { return sl::exp(x); }},
      {"log", [](const Tensor& x) { return sl::log(sl::add_scalar(sl::abs(x), 0.1)); }},
      {"tanh", [](const Tensor& x) { return sl::tanh(x); }},
      {"sigmoid", [](const Tensor& x) { return sl::sigmoid(x); }},
      {"softplus", [](const Tensor& x) { return sl::softplus(x); }},
      {"pow_scalar 2.2", [](const Tensor& x) { return sl::pow_scalar(sl::add_scalar(sl::abs(x), 0.1), 2.2); }},
      {"pow_scalar -1.5", [](const Tensor& x) { return sl::pow_scalar(sl::add_scalar(sl::abs(x), 0.1), -1.5); }}};
  const Tensor x32 = Tensor::uniform({100003}, -6, 6, 5, DType::F32);
  for (const auto& [name, f] : ops) {
    Tensor a = x32.clone().set_requires_grad(true);
    Tensor b = x32.to(DType::F64).set_requires_grad(true);  // the same inputs, exactly
    const Tensor ya = f(a), yb = f(b);
    backward(sl::sum(ya));
    backward(sl::sum(yb));
    const auto va = ya.to_vector(), vb = yb.to_vector(), ga = a.grad().to_vector(), gb = b.grad().to_vector();
    for (size_t i = 0; i < va.size(); ++i) {
      ASSERT_NEAR(va[i], vb[i], 4e-7 * std::max(1.0, std::fabs(vb[i]))) << name << " value at " << i;
      ASSERT_NEAR(ga[i], gb[i], 2e-6 * std::max(1.0, std::fabs(gb[i]))) << name << " grad at " << i;
    }
  }
}

// A float32 channel slice (a strided view, as vsg_activate's softplus / sigmoid of raw[:, a:b])
// takes the vectorised kernels row by row: values and gradients are bitwise those of the same op
// on a contiguous copy, for odd row lengths too. A view whose innermost stride is not 1 (a
// transpose) goes through libm and agrees to float precision.
TEST(VectorMath, StridedFloat32ViewsMatchContiguousBitwise) {
  using TensorFn = std::function<Tensor(const Tensor&)>;
  const std::vector<std::pair<const char*, TensorFn>> ops{
      {"exp", [](const Tensor& x) { return sl::exp(x); }},
      {"tanh", [](const Tensor& x) { return sl::tanh(x); }},
      {"sigmoid", [](const Tensor& x) { return sl::sigmoid(x); }},
      {"softplus", [](const Tensor& x) { return sl::softplus(x); }}};
  for (const Shape& shape : {Shape{2, 8, 5, 7}, Shape{3, 5, 33}, Shape{2, 9, 1, 17}, Shape{2, 4, 64, 65}}) {
    const Tensor base = Tensor::uniform(shape, -8, 8, 21, DType::F32);
    for (const auto& [name, f] : ops) {
      for (const auto& [lo, hi] : {std::pair<int64_t, int64_t>{0, 3}, {1, 2}, {2, 4}}) {
        Tensor parent_a = base.clone().set_requires_grad(true);
        Tensor parent_b = base.clone().set_requires_grad(true);
        const Tensor view = sl::slice(parent_a, 1, lo, hi);  // strided
        ASSERT_FALSE(view.is_contiguous());
        const Tensor copy = sl::slice(parent_b, 1, lo, hi).contiguous();
        const Tensor ya = f(view), yb = f(copy);
        const Tensor w = Tensor::uniform(ya.shape(), -1, 1, 22, DType::F32);  // a non-uniform upstream gradient
        backward(sl::sum(sl::mul(ya, w)));
        backward(sl::sum(sl::mul(yb, w)));
        const auto va = ya.to_vector(), vb = yb.to_vector();
        const auto ga = parent_a.grad().to_vector(), gb = parent_b.grad().to_vector();
        for (size_t i = 0; i < va.size(); ++i) ASSERT_EQ(va[i], vb[i]) << name << " value at " << i;
        for (size_t i = 0; i < ga.size(); ++i) ASSERT_EQ(ga[i], gb[i]) << name << " grad at " << i;
      }
      const Tensor t = sl::transpose(base, 1, static_cast<int64_t>(shape.size()) - 1);  // innermost stride != 1
      const auto vt = f(t).to_vector(), vc = f(t.contiguous()).to_vector();
      for (size_t i = 0; i < vt.size(); ++i) ASSERT_NEAR(vt[i], vc[i], 4e-7 * std::max(1.0, std::fabs(vc[i]))) << name;
    }
  }
}

}  // namespace
}  // namespace sl::test
