// RayMarcher: radiance_query()'s forward one ray at a time, or a batch in AVX-512 lanes
// (render/radiance_query.h).
#include "render/radiance_query.h"

#include <algorithm>
#include <cstddef>

#if defined(__AVX512F__)
#include <immintrin.h>
#endif

#include "autodiff/vector_math.h"
#include "render/radiance_march.h"
#include "util/parallel.h"

namespace sl::render {

using namespace detail;

struct RayMarcher::Projection : LogProjection<float> {
  using LogProjection<float>::LogProjection;
};

struct RayMarcher::Voxels {
  std::vector<VoxelRecord> record;  // [X·Y·Z], the planar volume's voxel order
  int64_t X = 0, Y = 0, Z = 0;
};

RayMarcher::RayMarcher(const Tensor& vsg, const Tensor& env, const VsgGrid& grid, const RadianceQueryOptions& options)
    : env_(env.detach().to(DType::F32).contiguous()), grid_(grid), opt_(options) {
  grid.validate();
  proj_ = std::make_shared<const Projection>(grid);
  SL_CHECK(options.samples >= 1, "RayMarcher: samples = ", options.samples, " must be >= 1");
  SL_CHECK(vsg.dim() == 4 && vsg.size(0) == 8 && vsg.size(1) == grid.dims[0] && vsg.size(2) == grid.dims[1] &&
               vsg.size(3) == grid.dims[2],
           "RayMarcher: vsg must be [8, ", grid.dims[0], ", ", grid.dims[1], ", ", grid.dims[2], "], got ",
           vsg.describe());
  SL_CHECK(env_.dim() == 3 && env_.size(0) == 3, "RayMarcher: env must be [3, H, W], got ", env.describe());
  const Tensor planes = vsg.detach().to(DType::F32).contiguous();
  auto voxels = std::make_shared<Voxels>();
  voxels->X = planes.size(1);
  voxels->Y = planes.size(2);
  voxels->Z = planes.size(3);
  const int64_t vox = voxels->X * voxels->Y * voxels->Z;
  voxels->record.resize(size_t(vox));
  const float* p = planes.data<float>();
  parallel_for(vox, 4096, [&](int64_t b, int64_t e) {
    for (int64_t v = b; v < e; ++v) {
      const sg::Lobe<float> lobe = lobe_at(p, vox, v);
      VoxelRecord& r = voxels->record[size_t(v)];
      for (int c = 0; c < 3; ++c) r.c[c] = lobe.c[c];
      sg::unit_axis(lobe.mu, r.muhat);
      r.sharpness = lobe.sharpness;
      r.alpha = p[7 * vox + v];
    }
  });
  voxels_ = std::move(voxels);
}

RayMarcher::Result RayMarcher::operator()(const float origin[3], const float dir[3]) const {
  const Voxels& vx = *voxels_;
  const Geometry geo{1, 1, vx.X, vx.Y, vx.Z, vx.X * vx.Y * vx.Z, env_.size(1), env_.size(2)};
  thread_local RayMarch<float> m;  // scratch: no allocation per ray after the first
  march(geo, grid_, *proj_, opt_, InterleavedVolume{vx.record.data()}, env_.data<float>(), origin, dir, m);
  float out[3], tr, d;
  composite(m, out, tr, d);
  return {glm::vec3(out[0], out[1], out[2]), tr};
}

void RayMarcher::operator()(int64_t n, const float* origins, const float* dirs, Result* out) const {
#if defined(__AVX512F__)
  const Voxels& vx = *voxels_;
  const int64_t vox = vx.X * vx.Y * vx.Z;
  // Byte offsets of the records must fit 32-bit gathers.
  if (!opt_.trilinear && vox < (int64_t{1} << 25) && n > 1) {
    march_lanes(n, origins, dirs, out);
    return;
  }
#endif
  for (int64_t i = 0; i < n; ++i) out[i] = (*this)(origins + 3 * i, dirs + 3 * i);
}

#if defined(__AVX512F__)
// 16 rays in the lanes of AVX-512 registers. Each ray's prefix (validity, L_env, clip, sample
// voxels) is march_prefix(), as in march(), L_env's panorama coordinates converted for the 16 as
// one batch (the same bits); then per sample k, all lanes at once: α from the
// sample's voxel, the lobe's exponent, e = vm::exp of all of them, and the sums of composite()
// with march()'s pruning and stop as lane masks. Every lane performs march()'s and composite()'s
// operations on its ray in their order (the same FMAs), so the bits are RayMarcher's
// (RayMarcher.BatchEqualsOneRayAtATime).
void RayMarcher::march_lanes(int64_t n, const float* origins, const float* dirs, Result* out) const {
  constexpr int kLanes = 16;
  const Voxels& vx = *voxels_;
  const Geometry geo{1, 1, vx.X, vx.Y, vx.Z, vx.X * vx.Y * vx.Z, env_.size(1), env_.size(2)};
  const float* env = env_.data<float>();
  const int K = opt_.samples;
  const bool grid_spacing = opt_.spacing == SampleSpacing::kGrid, prune = opt_.prune;
  thread_local RayMarch<float> m;
  thread_local std::vector<int32_t> offset_buffer;  // [k][lane] byte offset of the sample's voxel record
  thread_local std::vector<float> exp_buffer;       // [k][lane] the lobe's exponent, then its exponential
  if (offset_buffer.size() < size_t(K) * kLanes) {
    offset_buffer.resize(size_t(K) * kLanes);
    exp_buffer.resize(size_t(K) * kLanes);
  }
  int32_t* const offset = offset_buffer.data();
  float* const ex = exp_buffer.data();
  const char* const base = reinterpret_cast<const char*>(vx.record.data());
  constexpr int kC = offsetof(VoxelRecord, c), kMu = offsetof(VoxelRecord, muhat);
  constexpr int kSharp = offsetof(VoxelRecord, sharpness), kAlpha = offsetof(VoxelRecord, alpha);
  const __m512 zero = _mm512_setzero_ps(), one = _mm512_set1_ps(1.0f), half = _mm512_set1_ps(0.5f);
  const __m512 empty = _mm512_set1_ps(float(opt_.empty_alpha));
  const __m512i sign = _mm512_set1_epi32(int32_t(0x80000000u));  // −λ flips λ's sign bit, as −x does
  for (int64_t g0 = 0; g0 < n; g0 += kLanes) {
    const int lanes = int(std::min<int64_t>(kLanes, n - g0));
    alignas(64) float v[3][kLanes] = {}, sky[3][kLanes] = {}, stop[kLanes] = {};
    glm::vec3 l[kLanes];
    equirect::UV unit[kLanes];
    for (int j = 0; j < lanes; ++j) l[j] = glm::vec3(dirs[3 * (g0 + j)], dirs[3 * (g0 + j) + 1], dirs[3 * (g0 + j) + 2]);
    equirect::directions_to_units(lanes, l, unit);
    __mmask16 live = 0;
    for (int j = 0; j < kLanes; ++j) {
      const int64_t i = g0 + j;
      float s = 0;
      if (j < lanes && march_prefix(geo, grid_, *proj_, opt_, env, origins + 3 * i, dirs + 3 * i, m, s, &unit[j])) {
        live = __mmask16(live | (1u << j));
        for (int c = 0; c < 3; ++c) {
          v[c][j] = -m.dir[c];
          sky[c][j] = m.env[c];
        }
        stop[j] = s;
        for (int k = 0; k < K; ++k) offset[k * kLanes + j] = int32_t(m.nearest[size_t(k)] * int64_t(sizeof(VoxelRecord)));
        continue;
      }
      if (j < lanes) {  // no samples: composite() of the empty march
        float r[3], tr, d;
        composite(m, r, tr, d);
        out[i] = {glm::vec3(r[0], r[1], r[2]), tr};
      }
      for (int k = 0; k < K; ++k) offset[k * kLanes + j] = 0;
    }
    if (!live) continue;
    const __m512 v0 = _mm512_load_ps(v[0]), v1 = _mm512_load_ps(v[1]), v2 = _mm512_load_ps(v[2]);
    // sg::unit_axis_exponent: −λ·|v − μ̂|²/2 with |v − μ̂|² summed by FMAs in axis order.
    for (int k = 0; k < K; ++k) {
      const __m512i idx = _mm512_loadu_si512(offset + k * kLanes);
      const __m512 d0 = _mm512_sub_ps(v0, _mm512_i32gather_ps(idx, base + kMu, 1));
      const __m512 d1 = _mm512_sub_ps(v1, _mm512_i32gather_ps(idx, base + kMu + 4, 1));
      const __m512 d2 = _mm512_sub_ps(v2, _mm512_i32gather_ps(idx, base + kMu + 8, 1));
      const __m512 dist2 = _mm512_fmadd_ps(d2, d2, _mm512_fmadd_ps(d1, d1, _mm512_mul_ps(d0, d0)));
      const __m512 sharp = _mm512_i32gather_ps(idx, base + kSharp, 1);
      _mm512_storeu_ps(ex + k * kLanes, _mm512_mul_ps(_mm512_mul_ps(_mm512_castsi512_ps(_mm512_xor_si512(_mm512_castps_si512(sharp), sign)), dist2), half));
    }
    vm::exp(ex, ex, int64_t(K) * kLanes);
    __m512 r0 = zero, r1 = zero, r2 = zero, tau = one;
    const __m512 stop_v = _mm512_load_ps(stop);
    __mmask16 active = live, terminated = 0;
    __m512i previous = _mm512_set1_epi32(-1);
    for (int k = 0; k < K && active; ++k) {
      const __m512i idx = _mm512_loadu_si512(offset + k * kLanes);
      __mmask16 keep = active;
      if (grid_spacing) keep = _mm512_mask_cmpneq_epi32_mask(keep, idx, previous);  // a voxel once per crossing
      previous = idx;
      const __m512 alpha = _mm512_add_ps(zero, _mm512_i32gather_ps(idx, base + kAlpha, 1));  // 0 + 1·α
      if (prune) keep = _mm512_mask_cmp_ps_mask(keep, alpha, empty, _CMP_NLT_UQ);
      if (!keep) continue;
      const __m512 e = _mm512_loadu_ps(ex + k * kLanes);
      // g = 0 + 1·(c·e), as march() sums one tap.
      const __m512 g0 = _mm512_add_ps(_mm512_mul_ps(_mm512_i32gather_ps(idx, base + kC, 1), e), zero);
      const __m512 g1 = _mm512_add_ps(_mm512_mul_ps(_mm512_i32gather_ps(idx, base + kC + 4, 1), e), zero);
      const __m512 g2 = _mm512_add_ps(_mm512_mul_ps(_mm512_i32gather_ps(idx, base + kC + 8, 1), e), zero);
      const __m512 w = _mm512_mul_ps(tau, alpha);
      r0 = _mm512_mask3_fmadd_ps(w, g0, r0, keep);
      r1 = _mm512_mask3_fmadd_ps(w, g1, r1, keep);
      r2 = _mm512_mask3_fmadd_ps(w, g2, r2, keep);
      tau = _mm512_mask_mul_ps(tau, keep, tau, _mm512_sub_ps(one, alpha));
      if (prune) {
        const __mmask16 ended = _mm512_mask_cmp_ps_mask(keep, tau, stop_v, _CMP_LT_OQ);
        terminated = __mmask16(terminated | ended);
        active = __mmask16(active & ~ended);
      }
    }
    const __mmask16 open = __mmask16(live & ~terminated);  // the sky term where the march did not stop
    r0 = _mm512_mask3_fmadd_ps(tau, _mm512_load_ps(sky[0]), r0, open);
    r1 = _mm512_mask3_fmadd_ps(tau, _mm512_load_ps(sky[1]), r1, open);
    r2 = _mm512_mask3_fmadd_ps(tau, _mm512_load_ps(sky[2]), r2, open);
    alignas(64) float o0[kLanes], o1[kLanes], o2[kLanes], ot[kLanes];
    _mm512_store_ps(o0, r0);
    _mm512_store_ps(o1, r1);
    _mm512_store_ps(o2, r2);
    _mm512_store_ps(ot, tau);
    for (int j = 0; j < lanes; ++j)
      if (live & (1u << j)) out[g0 + j] = {glm::vec3(o0[j], o1[j], o2[j]), ot[j]};
  }
}
#endif

}  // namespace sl::render
