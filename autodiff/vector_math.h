// Vectorised float32 transcendental functions over arrays, with runtime ISA dispatch.
//
// Contract:
// - Each function reads n floats from x and writes n floats to y (x == y is allowed; other
//   overlap is not). n may be 0.
// - One algorithm, three instruction sets: AVX-512 (F, DQ, BW, VL: 16 lanes), AVX2 + FMA (8
//   lanes) and a scalar fallback (std::fma). Every level performs the same IEEE operations in
//   the same order, so the three give bitwise identical results for every input (tested), and
//   the result for one element depends only on that element (so on no thread count).
// - The level is chosen once from the CPU (cpuid) and can be lowered with the environment
//   variable STREETLIGHT_SIMD=scalar|avx2|avx512 or force_simd_level() (tests, benchmarks).
// - Accuracy against float64 libm, over every float including denormals (tested by
//   tests/autodiff/vector_math_test.cpp sweeping every 251st float bit pattern, both signs):
//     exp       ≤ 1 ulp      log       ≤ 1 ulp       tanh  ≤ 2 ulp
//     sigmoid   ≤ 2.5 ulp    softplus  ≤ 2 ulp       pow   ≤ 0.501 ulp (rounded once from double)
//   (the bounds asserted are the constants kMaxUlp* below; measured maxima at the time of
//   writing: exp 0.88, log 0.80, tanh 1.47, sigmoid 2.20, softplus 1.77, pow 0.500). libm's
//   float functions are within 1 ulp; PyTorch's vectorised (Sleef) ones within 1 to 3.5.
// - Special values follow C99 Annex F as std:: does: exp(-inf) = 0, exp(+inf) = inf,
//   exp overflows to inf above ~88.72 and underflows through the denormals to 0;
//   log(0) = -inf, log(x < 0) = NaN, log(inf) = inf; tanh(±inf) = ±1, tanh(-0) = -0;
//   sigmoid(-inf) = 0, sigmoid(inf) = 1; softplus(x) = max(x, 0) + log1p(exp(-|x|)) (never
//   overflows; softplus(inf) = inf); NaN in gives NaN out. pow follows std::pow for a scalar
//   exponent, including negative bases with integer exponents and signed zeros.
#pragma once
#include <cstdint>

namespace sl::vm {

enum class SimdLevel : int { Scalar = 0, Avx2 = 1, Avx512 = 2 };

// Worst-case error bounds (ulp of the float result against the float64 libm value) that the
// accuracy test asserts over the whole float range.
constexpr double kMaxUlpExp = 1.0;
constexpr double kMaxUlpLog = 1.0;
constexpr double kMaxUlpTanh = 2.0;
constexpr double kMaxUlpSigmoid = 2.5;
constexpr double kMaxUlpSoftplus = 2.0;
constexpr double kMaxUlpPow = 0.501;

// The best level this CPU supports (ignores STREETLIGHT_SIMD and force_simd_level).
SimdLevel cpu_simd_level();
// The level in use: cpu_simd_level(), lowered by STREETLIGHT_SIMD, or as forced.
SimdLevel active_simd_level();
// Uses `level` (clamped to what the CPU supports) from now on; returns the level now active.
SimdLevel force_simd_level(SimdLevel level);
const char* simd_level_name(SimdLevel level);

void exp(const float* x, float* y, int64_t n);
void log(const float* x, float* y, int64_t n);
void tanh(const float* x, float* y, int64_t n);
void sigmoid(const float* x, float* y, int64_t n);
void softplus(const float* x, float* y, int64_t n);
// y = x^p for a scalar exponent p (computed in double internally, rounded once).
void pow(const float* x, float p, float* y, int64_t n);

// Σ x[0..n) accumulated in double, in one fixed order on every level (32 interleaved partial
// sums combined pairwise, then the n mod 32 tail; vector_math_kernels.h sum_array): identical
// bits on scalar, AVX2 and AVX-512. The autodiff sum of float32 calls it per reduction block.
double sum(const float* x, int64_t n);

// Fused backward kernels: dx = g · f'(x) written to dx.
void softplus_backward(const float* g, const float* x, float* dx, int64_t n);  // g · sigmoid(x)

}  // namespace sl::vm
