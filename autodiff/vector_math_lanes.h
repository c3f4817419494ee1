// The lane wrappers of vector_math_kernels.h, written once for every instruction set (internal).
//
// Lanes<T, N> holds N lanes of T (float or double) in a GCC vector, so +, −, ×, ÷, comparisons,
// bit operations and ?: compile to the widest instructions the including unit is built for:
// vector_math_scalar.cpp (N = 1), vector_math_avx2.cpp (-mavx2 -mfma, N = 8 floats / 4
// doubles) and vector_math_avx512.cpp (-mavx512*, N = 16 / 8). The one operation C++ cannot
// spell on a vector is the fused multiply-add; fma() calls the instruction of the vector's width
// (std::fma one lane at a time for N = 1). Every operation is a fixed IEEE operation on each
// lane, and the units build with -ffp-contract=off, so the three levels agree bit for bit.
// Semantics match the x86 instructions: min/max return the second operand when either is NaN
// (MINPS/MAXPS), integer arithmetic wraps, masks are all-ones/all-zeros lanes. Each (T, N) is
// instantiated by one unit only, so no instruction set's code is shared with another's.
#pragma once
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <type_traits>

#include <immintrin.h>

namespace sl::vm::detail {

template <class T, int N>
struct Lanes {
  static_assert(std::is_same_v<T, float> || std::is_same_v<T, double>);
  using SInt = std::conditional_t<std::is_same_v<T, float>, int32_t, int64_t>;
  using UInt = std::make_unsigned_t<SInt>;
  static constexpr int kLanes = N;
  static constexpr int kBytes = N * static_cast<int>(sizeof(T));
  typedef T F __attribute__((vector_size(kBytes)));
  typedef SInt I __attribute__((vector_size(kBytes)));
  typedef UInt U __attribute__((vector_size(kBytes)));
  typedef float Stored __attribute__((vector_size(N * sizeof(float))));  // what load/store move
  using M = I;
  using D = F;

  // Loads N floats (widened to double for T = double); stores N floats (rounded once).
  static F load(const float* p) {
    // Widening float → double in one instruction (GCC splits __builtin_convertvector into two
    // half-width conversions and an insert; exact either way).
    if constexpr (kBytes == 64 && std::is_same_v<T, double>) {
      return (F)_mm512_cvtps_pd(_mm256_loadu_ps(p));
    } else if constexpr (kBytes == 32 && std::is_same_v<T, double>) {
      return (F)_mm256_cvtps_pd(_mm_loadu_ps(p));
    }
    Stored s;
    std::memcpy(&s, p, sizeof(s));
    return __builtin_convertvector(s, F);
  }
  static void store(float* p, F v) {
    const Stored s = __builtin_convertvector(v, Stored);
    std::memcpy(p, &s, sizeof(s));
  }
  static F set(T v) { return F{} + v; }
  static I seti(SInt v) { return I{} + v; }
  static F add(F a, F b) { return a + b; }
  static F sub(F a, F b) { return a - b; }
  static F mul(F a, F b) { return a * b; }
  static F div(F a, F b) { return a / b; }
  static F fma(F a, F b, F c) {
    if constexpr (kBytes == 64 && std::is_same_v<T, float>) {
      return (F)_mm512_fmadd_ps((__m512)a, (__m512)b, (__m512)c);
    } else if constexpr (kBytes == 64) {
      return (F)_mm512_fmadd_pd((__m512d)a, (__m512d)b, (__m512d)c);
    } else if constexpr (kBytes == 32 && std::is_same_v<T, float>) {
      return (F)_mm256_fmadd_ps((__m256)a, (__m256)b, (__m256)c);
    } else if constexpr (kBytes == 32) {
      return (F)_mm256_fmadd_pd((__m256d)a, (__m256d)b, (__m256d)c);
    } else {
      F r;
      for (int i = 0; i < N; ++i) r[i] = std::fma(a[i], b[i], c[i]);
      return r;
    }
  }
  static F min(F a, F b) { return a < b ? a : b; }
  static F max(F a, F b) { return a > b ? a : b; }
  static F abs(F a) { return as_float(as_int(a) & ~sign_bit()); }
  static F copysign(F a, F s) { return as_float((as_int(a) & ~sign_bit()) | (as_int(s) & sign_bit())); }
  static I sign_bit() { return seti(std::numeric_limits<SInt>::min()); }
  static I as_int(F v) { return (I)v; }
  static F as_float(I v) { return (F)v; }
  static I addi(I a, I b) { return (I)((U)a + (U)b); }
  static I subi(I a, I b) { return (I)((U)a - (U)b); }
  static I andi(I a, I b) { return a & b; }
  static I ori(I a, I b) { return a | b; }
  template <int K>
  static I slli(I a) { return (I)((U)a << K); }
  template <int K>
  static I srai(I a) { return a >> K; }
  template <int K>
  static I srli(I a) { return (I)((U)a >> K); }
  static F cvt(I a) { return __builtin_convertvector(a, F); }
  static M lt(F a, F b) { return a < b; }
  static M eq(F a, F b) { return a == b; }
  static M isnan(F a) { return a != a; }
  static M mand(M a, M b) { return a & b; }
  static M mor(M a, M b) { return a | b; }
  static F select(M m, F a, F b) { return m ? a : b; }
};

}  // namespace sl::vm::detail
