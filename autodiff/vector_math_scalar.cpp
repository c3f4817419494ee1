// Scalar fallback of vector_math.h: the same operations as the SIMD units, one lane at a time.
#include <cmath>
#include <cstring>

#include "autodiff/vector_math_kernels.h"

namespace sl::vm::detail {
namespace {

template <class T, class U>
T bits_as(U v) {
  static_assert(sizeof(T) == sizeof(U));
  T r;
  std::memcpy(&r, &v, sizeof(T));
  return r;
}

// Lane operations of the SIMD units. min/max reproduce x86 MINPS/MAXPS (second operand when
// either is NaN); integer arithmetic wraps as the vector instructions do.
template <class T, class I, class U>
struct ScalarLane {
  using F = T;
  using M = bool;
  static constexpr int kLanes = 1;
  static T set(T v) { return v; }
  static I seti(I v) { return v; }
  static T add(T a, T b) { return a + b; }
  static T sub(T a, T b) { return a - b; }
  static T mul(T a, T b) { return a * b; }
  static T div(T a, T b) { return a / b; }
  static T fma(T a, T b, T c) { return std::fma(a, b, c); }
  static T min(T a, T b) { return a < b ? a : b; }
  static T max(T a, T b) { return a > b ? a : b; }
  static T abs(T a) { return bits_as<T>(static_cast<I>(bits_as<U>(a) & ~sign_bit())); }
  static T copysign(T a, T s) {
    return bits_as<T>(static_cast<I>((bits_as<U>(a) & ~sign_bit()) | (bits_as<U>(s) & sign_bit())));
  }
  static constexpr U sign_bit() { return U{1} << (sizeof(U) * 8 - 1); }
  static I as_int(T v) { return bits_as<I>(v); }
  static T as_float(I v) { return bits_as<T>(v); }
  static I addi(I a, I b) { return static_cast<I>(static_cast<U>(a) + static_cast<U>(b)); }
  static I subi(I a, I b) { return static_cast<I>(static_cast<U>(a) - static_cast<U>(b)); }
  static I andi(I a, I b) { return a & b; }
  static I ori(I a, I b) { return a | b; }
  template <int K>
  static I slli(I a) { return static_cast<I>(static_cast<U>(a) << K); }
  template <int K>
  static I srai(I a) { return a >> K; }
  template <int K>
  static I srli(I a) { return static_cast<I>(static_cast<U>(a) >> K); }
  static T cvt(I a) { return static_cast<T>(a); }
  static bool lt(T a, T b) { return a < b; }
  static bool eq(T a, T b) { return a == b; }
  static bool isnan(T a) { return a != a; }
  static bool mand(bool a, bool b) { return a && b; }
  static bool mor(bool a, bool b) { return a || b; }
  static T select(bool m, T a, T b) { return m ? a : b; }
};

struct V : ScalarLane<float, int32_t, uint32_t> {
  static float load(const float* p) { return *p; }
  static void store(float* p, float v) { *p = v; }
};

struct VD : ScalarLane<double, int64_t, uint64_t> {
  using D = double;
  static double load(const float* p) { return static_cast<double>(*p); }
  static void store(float* p, double v) { *p = static_cast<float>(v); }
};

}  // namespace

SL_VM_DEFINE_TABLE(scalar_table, V, VD)

}  // namespace sl::vm::detail
