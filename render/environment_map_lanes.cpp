// Bilinear importance sampling of the sky, many draws at once (see environment_map.h).
//
// A draw of sample_bilinear_direction() is a chain of dependent double divisions and square
// roots (the guide-table searches, then the inverse CDFs of the cell's marginal and conditional)
// with data-dependent branches; pdf_bilinear_unit() is another chain. Under perf on an Intel
// Xeon (family 6 model 167) the two were about 13% of the KITTI insertion. Here the double
// arithmetic of 8 draws runs in AVX-512 lanes, written operation by operation as the scalar
// code compiles: every division, square root and conversion is correctly rounded, the searches
// are the same loops run until no lane moves, the clamps are the same comparisons (not min/max,
// which differ on −0), and the products GCC fuses in the scalar code (-ffp-contract=fast) are
// fused here (FMA intrinsics) and no others: GCC contracts intrinsics' products and sums too, so
// this file is compiled with -ffp-contract=off (render/CMakeLists.txt). So the bits are the same
// (EnvironmentMapLanes.* tests). The sines and cosines stay libm's, one lane at a time.
#include <cmath>

#if defined(__AVX512F__) && defined(__AVX512DQ__) && defined(__AVX512VL__)
#include <immintrin.h>
#define SL_ENV_LANES 1
#endif

#include "render/environment_map.h"
#include "util/math.h"

namespace sl::render {

void EnvironmentMap::sample_bilinear_directions_scalar(int n, const float* u1, const float* u2, glm::vec3* directions,
                                                       equirect::UV* units) const {
  for (int i = 0; i < n; ++i) directions[i] = sample_bilinear_direction(u1[i], u2[i], units[i]);
}

void EnvironmentMap::pdf_bilinear_units_scalar(int n, const equirect::UV* units, const double* cos_elevation,
                                               float* densities) const {
  for (int i = 0; i < n; ++i)
    densities[i] = cos_elevation ? pdf_bilinear_unit(units[i], cos_elevation[i]) : pdf_bilinear_unit(units[i]);
}

#if defined(SL_ENV_LANES)
namespace {

using V = __m512d;
using I = __m256i;
using M = __mmask8;

V splat(double x) { return _mm512_set1_pd(x); }
I splat_i(int x) { return _mm256_set1_epi32(x); }
// (a < b ? b : a), (b < a ? b : a): std::max / std::min with their operand order.
V max_of(V a, V b) { return _mm512_mask_blend_pd(_mm512_cmp_pd_mask(a, b, _CMP_LT_OQ), a, b); }
V min_of(V a, V b) { return _mm512_mask_blend_pd(_mm512_cmp_pd_mask(b, a, _CMP_LT_OQ), a, b); }
// std::clamp(x, 0, 1): x < 0 ? 0 : (1 < x ? 1 : x).
V clamp01(V x) {
  x = _mm512_mask_blend_pd(_mm512_cmp_pd_mask(splat(1.0), x, _CMP_LT_OQ), x, splat(1.0));
  return _mm512_mask_blend_pd(_mm512_cmp_pd_mask(x, splat(0.0), _CMP_LT_OQ), x, splat(0.0));
}
I clamp_i(I k, int lo, int hi) { return _mm256_min_epi32(_mm256_max_epi32(k, splat_i(lo)), splat_i(hi)); }
// The masked forms with a zero source: the plain ones start from an undefined register, which
// GCC 12 reports as uninitialised.
V gather(const double* base, I index) { return _mm512_mask_i32gather_pd(_mm512_setzero_pd(), 0xFF, index, base, 8); }
I truncate(V x) { return _mm512_maskz_cvttpd_epi32(0xFF, x); }
V gather_lum(const float* base, I index) { return _mm512_cvtps_pd(_mm256_i32gather_ps(base, index, 4)); }

// sample_linear() (environment_map.cpp): the inverse CDF of the density ∝ lerp(x, a, b) on
// [0, 1]; the scalar code fuses ((1 − u)·a)·a + (u·b)·b into one FMA, as here.
V sample_linear(V u, V a, V b) {
  const V t = _mm512_fmadd_pd(_mm512_mul_pd(_mm512_sub_pd(splat(1.0), u), a), a,
                              _mm512_mul_pd(_mm512_mul_pd(u, b), b));
  const V s = _mm512_sqrt_pd(max_of(splat(0.0), t));
  const V x = clamp01(_mm512_div_pd(_mm512_mul_pd(u, _mm512_add_pd(a, b)), _mm512_add_pd(a, s)));
  return _mm512_mask_blend_pd(_mm512_cmp_pd_mask(a, b, _CMP_EQ_OQ), x, u);
}

// The pick() of sample_bilinear_direction in lanes: the cell k of n (per lane, its CDF at
// cdf[offset + ·] and its guide table at guide[guide_offset + ·]) with cdf[k] <= u < cdf[k + 1],
// and u's fraction inside it.
I pick(const double* cdf, I offset, const int* guide, I guide_offset, int n, V u, V& frac) {
  const I start = clamp_i(truncate(_mm512_mul_pd(u, splat(double(n)))), 0, n - 1);
  I k = _mm256_i32gather_epi32(guide, _mm256_add_epi32(guide_offset, start), 4);
  const I zero = _mm256_setzero_si256(), last = splat_i(n - 1), one = splat_i(1);
  auto at = [&](I kk) { return gather(cdf, _mm256_add_epi32(offset, kk)); };
  for (;;) {  // u·n rounded up into the next entry
    const M m = _mm256_cmpgt_epi32_mask(k, zero) & _mm512_cmp_pd_mask(at(k), u, _CMP_GT_OQ);
    if (!m) break;
    k = _mm256_mask_sub_epi32(k, m, k, one);
  }
  for (;;) {
    const M m = _mm256_cmplt_epi32_mask(k, last) & _mm512_cmp_pd_mask(at(_mm256_add_epi32(k, one)), u, _CMP_LE_OQ);
    if (!m) break;
    k = _mm256_mask_add_epi32(k, m, k, one);
  }
  auto empty = [&](I kk) {
    return _mm512_cmp_pd_mask(_mm512_sub_pd(at(_mm256_add_epi32(kk, one)), at(kk)), splat(0.0), _CMP_LE_OQ);
  };
  for (;;) {
    const M m = _mm256_cmpgt_epi32_mask(k, zero) & empty(k);
    if (!m) break;
    k = _mm256_mask_sub_epi32(k, m, k, one);
  }
  for (;;) {
    const M m = _mm256_cmplt_epi32_mask(k, last) & empty(k);
    if (!m) break;
    k = _mm256_mask_add_epi32(k, m, k, one);
  }
  const V lo = at(k), w = _mm512_sub_pd(at(_mm256_add_epi32(k, one)), lo);
  frac = _mm512_mask_blend_pd(_mm512_cmp_pd_mask(w, splat(0.0), _CMP_GT_OQ), splat(0.5),
                              clamp01(_mm512_div_pd(_mm512_sub_pd(u, lo), w)));
  return k;
}

// cell_row(k, H) (environment_map.cpp): the cell row's v range and its two texel rows.
struct CellRows {
  V v0, v1;
  I top, bottom;
};
CellRows cell_rows(I k, int H) {
  const V kd = _mm512_cvtepi32_pd(k);
  return {max_of(splat(0.0), _mm512_sub_pd(kd, splat(0.5))), min_of(splat(double(H)), _mm512_add_pd(kd, splat(0.5))),
          _mm256_max_epi32(_mm256_sub_epi32(k, splat_i(1)), _mm256_setzero_si256()), _mm256_min_epi32(k, splat_i(H - 1))};
}

// next_column(c, W): c + 1, or 0 at the seam.
I next_columns(I c, int W) {
  const I c1 = _mm256_add_epi32(c, splat_i(1));
  return _mm256_mask_blend_epi32(_mm256_cmpeq_epi32_mask(c1, splat_i(W)), c1, _mm256_setzero_si256());
}

bool all_in_01(V u) {
  return _mm512_cmp_pd_mask(u, splat(0.0), _CMP_GE_OQ) == 0xFF && _mm512_cmp_pd_mask(u, splat(1.0), _CMP_LE_OQ) == 0xFF;
}

}  // namespace
#endif

void EnvironmentMap::sample_bilinear_directions(int n, const float* u1, const float* u2, glm::vec3* directions,
                                                equirect::UV* units) const {
  int i = 0;
#if defined(SL_ENV_LANES)
  const int H = height_, W = width_;
  // The lanes index the tables with 32-bit offsets.
  if (!cell_prob_.empty() && int64_t(H + 1) * (W + 1) < (int64_t(1) << 30)) {
    alignas(64) double unit_u[8], unit_v[8];
    alignas(32) float azimuth[8], elevation[8];
    const I row_w = splat_i(W), row_w1 = splat_i(W + 1);
    for (; i + 8 <= n; i += 8) {
      const V r1 = _mm512_cvtps_pd(_mm256_loadu_ps(u1 + i)), r2 = _mm512_cvtps_pd(_mm256_loadu_ps(u2 + i));
      if (!all_in_01(r1) || !all_in_01(r2)) {  // outside [0, 1] or NaN: the scalar loop's handling
        sample_bilinear_directions_scalar(8, u1 + i, u2 + i, directions + i, units + i);
        continue;
      }
      V fr, fc;
      const I zero = _mm256_setzero_si256();
      const I k = pick(cell_row_cdf_.data(), zero, cell_row_guide_.data(), zero, H + 1, r1, fr);
      const I c = pick(cell_col_cdf_.data(), _mm256_mullo_epi32(k, row_w1), cell_col_guide_.data(),
                       _mm256_mullo_epi32(k, row_w), W, r2, fc);
      const CellRows r = cell_rows(k, H);
      const I c1 = next_columns(c, W);
      const I top = _mm256_mullo_epi32(r.top, row_w), bottom = _mm256_mullo_epi32(r.bottom, row_w);
      const float* lum = lum_.data();
      const V a = gather_lum(lum, _mm256_add_epi32(top, c)), b = gather_lum(lum, _mm256_add_epi32(top, c1));
      const V cc = gather_lum(lum, _mm256_add_epi32(bottom, c)), d = gather_lum(lum, _mm256_add_epi32(bottom, c1));
      // The bilinear patch: marginal in y ∝ lerp(y, a + b, c + d), then x | y ∝ lerp(x, left, right)
      // (left and right unfused, as the scalar code computes them).
      const V y = sample_linear(fr, _mm512_add_pd(a, b), _mm512_add_pd(cc, d));
      const V y1 = _mm512_sub_pd(splat(1.0), y);
      const V left = _mm512_add_pd(_mm512_mul_pd(y1, a), _mm512_mul_pd(y, cc));
      const V right = _mm512_add_pd(_mm512_mul_pd(y1, b), _mm512_mul_pd(y, d));
      const V x = sample_linear(fc, left, right);
      const V v = _mm512_fmadd_pd(_mm512_sub_pd(r.v1, r.v0), y, r.v0);
      V u = _mm512_add_pd(_mm512_add_pd(_mm512_cvtepi32_pd(c), splat(0.5)), x);
      u = _mm512_mask_sub_pd(u, _mm512_cmp_pd_mask(u, splat(double(W)), _CMP_GE_OQ), u, splat(double(W)));
      const V uu = _mm512_div_pd(u, splat(double(W))), vv = _mm512_div_pd(v, splat(double(H)));
      _mm512_store_pd(unit_u, uu);
      _mm512_store_pd(unit_v, vv);
      _mm256_store_ps(azimuth, _mm512_cvtpd_ps(_mm512_mul_pd(_mm512_sub_pd(uu, splat(0.5)), splat(kTwoPi))));
      _mm256_store_ps(elevation, _mm512_cvtpd_ps(_mm512_mul_pd(_mm512_sub_pd(splat(0.5), vv), splat(kPi))));
      for (int j = 0; j < 8; ++j) {
        units[i + j] = {unit_u[j], unit_v[j]};
        const float ce = std::cos(elevation[j]);
        directions[i + j] = glm::vec3(ce * std::sin(azimuth[j]), std::sin(elevation[j]), -ce * std::cos(azimuth[j]));
      }
    }
  }
#endif
  sample_bilinear_directions_scalar(n - i, u1 + i, u2 + i, directions + i, units + i);
}

void EnvironmentMap::pdf_bilinear_units(int n, const equirect::UV* units, const double* cos_elevation,
                                        float* densities) const {
  int i = 0;
#if defined(SL_ENV_LANES)
  const int H = height_, W = width_;
  if (!cell_prob_.empty() && int64_t(H + 1) * (W + 1) < (int64_t(1) << 30)) {
    alignas(64) double uu[8], vv[8], ce[8];
    alignas(32) float out[8];
    const I row_w = splat_i(W);
    // (cos_elevation · 2π/W) · π/H, the Jacobian of the scalar code (its two quotients included).
    const V du = splat(kTwoPi / W), dv = splat(kPi / H);
    for (; i + 8 <= n; i += 8) {
      for (int j = 0; j < 8; ++j) {
        uu[j] = units[i + j].u;
        vv[j] = units[i + j].v;
        ce[j] = cos_elevation ? cos_elevation[i + j] : std::cos((0.5 - vv[j]) * kPi);
      }
      const V uv_u = _mm512_mul_pd(_mm512_load_pd(uu), splat(double(W)));
      const V uv_v = _mm512_mul_pd(_mm512_load_pd(vv), splat(double(H)));
      const V fv = _mm512_roundscale_pd(_mm512_add_pd(uv_v, splat(0.5)), _MM_FROUND_TO_NEG_INF | _MM_FROUND_NO_EXC);
      const V fu = _mm512_sub_pd(uv_u, splat(0.5));
      const V fl = _mm512_roundscale_pd(fu, _MM_FROUND_TO_NEG_INF | _MM_FROUND_NO_EXC);
      // Lanes whose rows or columns lie beyond one period (or are NaN) take the scalar path,
      // which wraps them with a modulo.
      const V big = splat(1 << 29);
      if (_mm512_cmp_pd_mask(fv, -big, _CMP_GE_OQ) != 0xFF || _mm512_cmp_pd_mask(fv, big, _CMP_LE_OQ) != 0xFF ||
          _mm512_cmp_pd_mask(fl, splat(-double(W)), _CMP_GE_OQ) != 0xFF ||
          _mm512_cmp_pd_mask(fl, splat(2.0 * W), _CMP_LT_OQ) != 0xFF) {
        pdf_bilinear_units_scalar(8, units + i, cos_elevation ? cos_elevation + i : nullptr, densities + i);
        continue;
      }
      const I k = clamp_i(truncate(fv), 0, H);
      const CellRows r = cell_rows(k, H);
      I c = truncate(fl);
      c = _mm256_mask_add_epi32(c, _mm256_cmplt_epi32_mask(c, _mm256_setzero_si256()), c, row_w);
      c = _mm256_mask_sub_epi32(c, _mm256_cmpge_epi32_mask(c, row_w), c, row_w);
      const I c1 = next_columns(c, W);
      const V x = clamp01(_mm512_sub_pd(fu, fl));
      const V span = _mm512_sub_pd(r.v1, r.v0);
      const V y = clamp01(_mm512_div_pd(_mm512_sub_pd(uv_v, r.v0), span));
      const I top = _mm256_mullo_epi32(r.top, row_w), bottom = _mm256_mullo_epi32(r.bottom, row_w);
      const float* lum = lum_.data();
      const V a = gather_lum(lum, _mm256_add_epi32(top, c)), b = gather_lum(lum, _mm256_add_epi32(top, c1));
      const V cc = gather_lum(lum, _mm256_add_epi32(bottom, c)), dd = gather_lum(lum, _mm256_add_epi32(bottom, c1));
      const V mean = _mm512_mul_pd(splat(0.25), _mm512_add_pd(_mm512_add_pd(_mm512_add_pd(a, b), cc), dd));
      const V x1 = _mm512_sub_pd(splat(1.0), x), y1 = _mm512_sub_pd(splat(1.0), y);
      const V upper = _mm512_fmadd_pd(x, b, _mm512_mul_pd(x1, a)), lower = _mm512_fmadd_pd(x, dd, _mm512_mul_pd(x1, cc));
      const V value = _mm512_fmadd_pd(y, lower, _mm512_mul_pd(y1, upper));
      const V j = _mm512_mul_pd(_mm512_mul_pd(_mm512_load_pd(ce), du), dv);
      const V prob = gather(cell_prob_.data(), _mm256_add_epi32(_mm256_mullo_epi32(k, row_w), c));
      const V p = _mm512_div_pd(_mm512_div_pd(_mm512_mul_pd(prob, value), _mm512_mul_pd(span, mean)), j);
      const M finite = _mm512_cmp_pd_mask(_mm512_abs_pd(p), splat(INFINITY), _CMP_LT_OQ);
      const M valid = _mm512_cmp_pd_mask(mean, splat(0.0), _CMP_GT_OQ) & _mm512_cmp_pd_mask(j, splat(1e-12), _CMP_GT_OQ);
      _mm256_store_ps(out, _mm256_maskz_mov_ps(finite & valid, _mm512_cvtpd_ps(p)));
      for (int q = 0; q < 8; ++q) densities[i + q] = out[q];
    }
  }
#endif
  pdf_bilinear_units_scalar(n - i, units + i, cos_elevation ? cos_elevation + i : nullptr, densities + i);
}

}  // namespace sl::render
