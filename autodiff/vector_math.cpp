#include "autodiff/vector_math.h"

#include <atomic>
#include <cmath>
#include <cstdlib>
#include <cstring>

#include "autodiff/vector_math_kernels.h"

namespace sl::vm {
namespace {

SimdLevel detect() {
#if defined(__x86_64__) || defined(__i386__)
  __builtin_cpu_init();
  if (__builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx512dq") &&
      __builtin_cpu_supports("avx512bw") && __builtin_cpu_supports("avx512vl"))
    return SimdLevel::Avx512;
  if (__builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma")) return SimdLevel::Avx2;
#endif
  return SimdLevel::Scalar;
}

SimdLevel from_environment(SimdLevel cpu) {
  const char* env = std::getenv("STREETLIGHT_SIMD");
  if (!env) return cpu;
  SimdLevel want = cpu;
  if (!std::strcmp(env, "scalar")) want = SimdLevel::Scalar;
  else if (!std::strcmp(env, "avx2")) want = SimdLevel::Avx2;
  else if (!std::strcmp(env, "avx512")) want = SimdLevel::Avx512;
  return static_cast<int>(want) < static_cast<int>(cpu) ? want : cpu;
}

std::atomic<int>& level_slot() {
  static std::atomic<int> slot{static_cast<int>(from_environment(cpu_simd_level()))};
  return slot;
}

const detail::Table& table() {
  switch (static_cast<SimdLevel>(level_slot().load(std::memory_order_relaxed))) {
    case SimdLevel::Avx512: return detail::avx512_table();
    case SimdLevel::Avx2: return detail::avx2_table();
    default: return detail::scalar_table();
  }
}

}  // namespace

SimdLevel cpu_simd_level() {
  static const SimdLevel level = detect();
  return level;
}

SimdLevel active_simd_level() { return static_cast<SimdLevel>(level_slot().load()); }

SimdLevel force_simd_level(SimdLevel level) {
  const SimdLevel cpu = cpu_simd_level();
  const SimdLevel use = static_cast<int>(level) < static_cast<int>(cpu) ? level : cpu;
  level_slot().store(static_cast<int>(use));
  return use;
}

const char* simd_level_name(SimdLevel level) {
  switch (level) {
    case SimdLevel::Avx512: return "avx512";
    case SimdLevel::Avx2: return "avx2";
    default: return "scalar";
  }
}

double sum(const float* x, int64_t n) { return table().sum(x, n); }
void exp(const float* x, float* y, int64_t n) { table().exp(x, y, n); }
void log(const float* x, float* y, int64_t n) { table().log(x, y, n); }
void tanh(const float* x, float* y, int64_t n) { table().tanh(x, y, n); }
void sigmoid(const float* x, float* y, int64_t n) { table().sigmoid(x, y, n); }
void softplus(const float* x, float* y, int64_t n) { table().softplus(x, y, n); }

void pow(const float* x, float p, float* y, int64_t n) {
  if (p == 0.0f || !std::isfinite(p)) {  // C99 special exponents: rare, exact through libm
    for (int64_t i = 0; i < n; ++i) y[i] = std::pow(x[i], p);
    return;
  }
  const bool integer = std::nearbyint(p) == p;
  const bool odd = integer && std::fabs(std::fmod(p, 2.0f)) == 1.0f;
  table().pow(x, y, n, p, integer, odd);
}

void softplus_backward(const float* g, const float* x, float* dx, int64_t n) {
  table().softplus_backward(g, x, dx, n);
}

}  // namespace sl::vm
