// Unit panorama coordinates of many directions at once (see equirect.h).
//
// direction_to_uv spends an asin and an atan2 of libm per direction; the insertion's inner loops
// convert millions (the shadow rays' cosine draws, the light rays' BRDF draws, the control
// variate's normals, the ray marcher's sky lookups), and under perf on an Intel Xeon the two were
// 4.3% of the cycles of streetlight-bench insert --size kitti (1 thread). Here both angles are
// one arctangent of a ratio in [0, 1]:
//   θ = atan2(y, √(x² + z²)),  φ = atan2(x, −z),
// each reduced the way atan2 is (t = min/max of the two magnitudes, then π/2 − ·, π − · and the
// sign), with atan(t) = t·P(t²) the minimax polynomial of scripts/fit_atan_poly.py (11 terms,
// 1.4e-10 rad). atan2(y, h) is accurate at the poles, where asin(y) is not, and needs no
// normalisation. In 8 AVX-512 lanes the arithmetic is the scalar form's, operation by operation,
// and its fused products are written as fma on both sides; this file is compiled with
// -ffp-contract=off (render/CMakeLists.txt) so that GCC fuses no others, and the bits agree.
#include <cfloat>
#include <cmath>

#if defined(__AVX512F__) && defined(__AVX512DQ__) && defined(__AVX512VL__)
#include <immintrin.h>
#define SL_EQUIRECT_LANES 1
#endif

#include "render/equirect.h"
#include "util/math.h"

namespace sl::render::equirect {
namespace {

// atan(t) ≈ t·P(t²) on [0, 1] (scripts/fit_atan_poly.py --terms 11), t¹ first.
constexpr double kAtan[] = {0.9999999966724551,    -0.33333302089698286,  0.19999129801401905,
                            -0.14274432172975676,  0.1102865140869567,    -0.08713861704123967,
                            0.06541381805569668,   -0.042088159804282266, 0.020467886772393726,
                            -0.006394794503061944, 0.0009375639113462654};
constexpr int kTerms = int(sizeof kAtan / sizeof kAtan[0]);
constexpr double kHalfPi = 0.5 * kPi, kInvTwoPi = 1.0 / kTwoPi, kInvPi = 1.0 / kPi;

// a·b + c, fused where the CPU fuses (as the lanes do); without FMA, libm's std::fma would be a
// slow software routine, so the product is rounded first.
inline double fmadd(double a, double b, double c) {
#if defined(__FMA__)
  return std::fma(a, b, c);
#else
  return a * b + c;
#endif
}

// atan2(a, b) of magnitudes a, b >= 0 (not both 0: that gives 0), in [0, π/2].
double atan_magnitudes(double a, double b) {
  const double t = std::min(a, b) / std::max(std::max(a, b), DBL_MIN), s = t * t;
  double p = kAtan[kTerms - 1];
  for (int k = kTerms - 2; k >= 0; --k) p = fmadd(p, s, kAtan[k]);
  const double r = t * p;
  return a > b ? kHalfPi - r : r;
}

}  // namespace

UV direction_to_unit(float x, float y, float z) {
  if (!std::isfinite(x) || !std::isfinite(y) || !std::isfinite(z)) return direction_to_uv(x, y, z, 1, 1);
  const double xd = x, yd = y, zd = z;
  const double h = std::sqrt(fmadd(xd, xd, zd * zd));
  // φ: the far half (−z <= −0, as atan2 reads a signed zero) is π − the near one.
  double azimuth = atan_magnitudes(std::abs(xd), std::abs(zd));
  if (!std::signbit(zd)) azimuth = kPi - azimuth;
  azimuth = std::copysign(azimuth, xd);
  const double elevation = std::copysign(atan_magnitudes(std::abs(yd), h), yd);
  const double u = (h == 0.0 && yd == 0.0) ? 0.5 : fmadd(azimuth, kInvTwoPi, 0.5);
  return {u, fmadd(-elevation, kInvPi, 0.5)};
}

#if defined(SL_EQUIRECT_LANES)
namespace {

using V = __m512d;
using M = __mmask8;

V splat(double x) { return _mm512_set1_pd(x); }

// atan_magnitudes() in lanes. max/min of non-negative finite values, where their operand order
// does not matter (no NaN; a zero is +0 after abs).
V atan_magnitudes(V a, V b) {
  const V t = _mm512_div_pd(_mm512_min_pd(a, b), _mm512_max_pd(_mm512_max_pd(a, b), splat(DBL_MIN)));
  const V s = _mm512_mul_pd(t, t);
  V p = splat(kAtan[kTerms - 1]);
  for (int k = kTerms - 2; k >= 0; --k) p = _mm512_fmadd_pd(p, s, splat(kAtan[k]));
  const V r = _mm512_mul_pd(t, p);
  return _mm512_mask_sub_pd(r, _mm512_cmp_pd_mask(a, b, _CMP_GT_OQ), splat(kHalfPi), r);
}

// x, y, z of 8 packed glm::vec3 (24 floats), widened to double.
void load_directions(const glm::vec3* d, V& x, V& y, V& z) {
  const float* f = &d[0].x;
  const __m512 lo = _mm512_loadu_ps(f), hi = _mm512_castps256_ps512(_mm256_loadu_ps(f + 16));
  const __m512i ix = _mm512_setr_epi32(0, 3, 6, 9, 12, 15, 18, 21, 0, 0, 0, 0, 0, 0, 0, 0);
  const __m512i one = _mm512_set1_epi32(1);
  const __m512i iy = _mm512_add_epi32(ix, one), iz = _mm512_add_epi32(iy, one);
  x = _mm512_cvtps_pd(_mm512_castps512_ps256(_mm512_permutex2var_ps(lo, ix, hi)));
  y = _mm512_cvtps_pd(_mm512_castps512_ps256(_mm512_permutex2var_ps(lo, iy, hi)));
  z = _mm512_cvtps_pd(_mm512_castps512_ps256(_mm512_permutex2var_ps(lo, iz, hi)));
}

bool all_finite(V x) { return _mm512_cmp_pd_mask(_mm512_abs_pd(x), splat(INFINITY), _CMP_LT_OQ) == 0xFF; }

V with_sign_of(V magnitude, V sign) {
  const V sign_bit = splat(-0.0);
  return _mm512_or_pd(magnitude, _mm512_and_pd(sign, sign_bit));
}

}  // namespace
#endif

void directions_to_units(int n, const glm::vec3* directions, UV* units) {
  static_assert(sizeof(glm::vec3) == 3 * sizeof(float) && sizeof(UV) == 2 * sizeof(double));
  int i = 0;
#if defined(SL_EQUIRECT_LANES)
  const __m512i first = _mm512_setr_epi64(0, 8, 1, 9, 2, 10, 3, 11), second = _mm512_setr_epi64(4, 12, 5, 13, 6, 14, 7, 15);
  for (; i + 8 <= n; i += 8) {
    V x, y, z;
    load_directions(directions + i, x, y, z);
    if (!all_finite(x) || !all_finite(y) || !all_finite(z)) {  // direction_to_uv's handling
      for (int j = i; j < i + 8; ++j) units[j] = direction_to_unit(directions[j].x, directions[j].y, directions[j].z);
      continue;
    }
    const V h = _mm512_sqrt_pd(_mm512_fmadd_pd(x, x, _mm512_mul_pd(z, z)));
    V azimuth = atan_magnitudes(_mm512_abs_pd(x), _mm512_abs_pd(z));
    const M near = _mm512_movepi64_mask(_mm512_castpd_si512(z));  // z's sign bit: −z >= +0
    azimuth = _mm512_mask_sub_pd(azimuth, M(~near), splat(kPi), azimuth);
    azimuth = with_sign_of(azimuth, x);
    const V elevation = with_sign_of(atan_magnitudes(_mm512_abs_pd(y), h), y);
    const M zero = _mm512_cmp_pd_mask(h, splat(0.0), _CMP_EQ_OQ) & _mm512_cmp_pd_mask(y, splat(0.0), _CMP_EQ_OQ);
    const V u = _mm512_mask_blend_pd(zero, _mm512_fmadd_pd(azimuth, splat(kInvTwoPi), splat(0.5)), splat(0.5));
    const V v = _mm512_fnmadd_pd(elevation, splat(kInvPi), splat(0.5));
    double* out = &units[i].u;
    _mm512_storeu_pd(out, _mm512_permutex2var_pd(u, first, v));
    _mm512_storeu_pd(out + 8, _mm512_permutex2var_pd(u, second, v));
  }
#endif
  for (; i < n; ++i) units[i] = direction_to_unit(directions[i].x, directions[i].y, directions[i].z);
}

}  // namespace sl::render::equirect
