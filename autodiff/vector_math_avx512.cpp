// AVX-512 (F, DQ, BW, VL) unit of vector_math.h (16 float lanes, 8 double lanes for pow). Built
// with -mavx512f -mavx512dq -mavx512bw -mavx512vl -mfma (autodiff/CMakeLists.txt) and called
// only when the CPU has all of them.
#include <immintrin.h>

#include "autodiff/vector_math_kernels.h"

namespace sl::vm::detail {
namespace {

struct V {
  using F = __m512;
  using I = __m512i;
  using M = __mmask16;
  static constexpr int kLanes = 16;
  static F load(const float* p) { return _mm512_loadu_ps(p); }
  static void store(float* p, F v) { _mm512_storeu_ps(p, v); }
  static F set(float v) { return _mm512_set1_ps(v); }
  static I seti(int32_t v) { return _mm512_set1_epi32(v); }
  static F add(F a, F b) { return _mm512_add_ps(a, b); }
  static F sub(F a, F b) { return _mm512_sub_ps(a, b); }
  static F mul(F a, F b) { return _mm512_mul_ps(a, b); }
  static F div(F a, F b) { return _mm512_div_ps(a, b); }
  static F fma(F a, F b, F c) { return _mm512_fmadd_ps(a, b, c); }
  static F min(F a, F b) { return _mm512_min_ps(a, b); }
  static F max(F a, F b) { return _mm512_max_ps(a, b); }
  static F abs(F a) { return _mm512_abs_ps(a); }
  static F copysign(F a, F s) {
    const I sign = _mm512_set1_epi32(static_cast<int32_t>(0x80000000u));
    return as_float(_mm512_or_si512(_mm512_andnot_si512(sign, as_int(a)), _mm512_and_si512(sign, as_int(s))));
  }
  static I as_int(F v) { return _mm512_castps_si512(v); }
  static F as_float(I v) { return _mm512_castsi512_ps(v); }
  static I addi(I a, I b) { return _mm512_add_epi32(a, b); }
  static I subi(I a, I b) { return _mm512_sub_epi32(a, b); }
  static I andi(I a, I b) { return _mm512_and_si512(a, b); }
  static I ori(I a, I b) { return _mm512_or_si512(a, b); }
  template <int K>
  static I slli(I a) { return _mm512_slli_epi32(a, K); }
  template <int K>
  static I srai(I a) { return _mm512_srai_epi32(a, K); }
  static F cvt(I a) { return _mm512_cvtepi32_ps(a); }
  static M lt(F a, F b) { return _mm512_cmp_ps_mask(a, b, _CMP_LT_OQ); }
  static M eq(F a, F b) { return _mm512_cmp_ps_mask(a, b, _CMP_EQ_OQ); }
  static M isnan(F a) { return _mm512_cmp_ps_mask(a, a, _CMP_UNORD_Q); }
  static M mand(M a, M b) { return static_cast<M>(a & b); }
  static M mor(M a, M b) { return static_cast<M>(a | b); }
  static F select(M m, F a, F b) { return _mm512_mask_blend_ps(m, b, a); }
};

struct VD {
  using D = __m512d;
  using F = __m512d;
  using I = __m512i;
  using M = __mmask8;
  static constexpr int kLanes = 8;
  static D load(const float* p) { return _mm512_cvtps_pd(_mm256_loadu_ps(p)); }
  static void store(float* p, D v) { _mm256_storeu_ps(p, _mm512_cvtpd_ps(v)); }
  static D set(double v) { return _mm512_set1_pd(v); }
  static I seti(int64_t v) { return _mm512_set1_epi64(v); }
  static D add(D a, D b) { return _mm512_add_pd(a, b); }
  static D sub(D a, D b) { return _mm512_sub_pd(a, b); }
  static D mul(D a, D b) { return _mm512_mul_pd(a, b); }
  static D div(D a, D b) { return _mm512_div_pd(a, b); }
  static D fma(D a, D b, D c) { return _mm512_fmadd_pd(a, b, c); }
  static D min(D a, D b) { return _mm512_min_pd(a, b); }
  static D max(D a, D b) { return _mm512_max_pd(a, b); }
  static D abs(D a) { return _mm512_abs_pd(a); }
  static D copysign(D a, D s) {
    const I sign = _mm512_set1_epi64(static_cast<int64_t>(0x8000000000000000ull));
    return as_float(_mm512_or_si512(_mm512_andnot_si512(sign, as_int(a)), _mm512_and_si512(sign, as_int(s))));
  }
  static I as_int(D v) { return _mm512_castpd_si512(v); }
  static D as_float(I v) { return _mm512_castsi512_pd(v); }
  static I addi(I a, I b) { return _mm512_add_epi64(a, b); }
  static I subi(I a, I b) { return _mm512_sub_epi64(a, b); }
  static I andi(I a, I b) { return _mm512_and_si512(a, b); }
  static I ori(I a, I b) { return _mm512_or_si512(a, b); }
  template <int K>
  static I slli(I a) { return _mm512_slli_epi64(a, K); }
  template <int K>
  static I srli(I a) { return _mm512_srli_epi64(a, K); }
  static M lt(D a, D b) { return _mm512_cmp_pd_mask(a, b, _CMP_LT_OQ); }
  static M eq(D a, D b) { return _mm512_cmp_pd_mask(a, b, _CMP_EQ_OQ); }
  static M isnan(D a) { return _mm512_cmp_pd_mask(a, a, _CMP_UNORD_Q); }
  static M mand(M a, M b) { return static_cast<M>(a & b); }
  static M mor(M a, M b) { return static_cast<M>(a | b); }
  static D select(M m, D a, D b) { return _mm512_mask_blend_pd(m, b, a); }
};

}  // namespace

SL_VM_DEFINE_TABLE(avx512_table, V, VD)

}  // namespace sl::vm::detail
