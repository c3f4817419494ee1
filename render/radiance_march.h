// The march of Eq. 1 along one ray (render/radiance_query.h): sample distances, voxel lookups,
// pruning, the lobes' exponentials and the sums, shared by the radiance_query op
// (radiance_query.cpp, on the tape) and RayMarcher (ray_marcher.cpp, off it), so that both give
// the same bits. Internal to render/.
//
// Contract: march_prefix() + march() fill a RayMarch with the kept samples of one ray exactly
// as the header of radiance_query.h describes them (forward and backward recompute them alike);
// composite() sums them into radiance, τ_K and depth. A Volume is read through alpha(v),
// colour(v, c), exponent(v, −l) and, for float64, lobe(v): PlanarVolume over the op's channel
// planes or InterleavedVolume over RayMarcher's per-voxel records, the same values.
#pragma once
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <type_traits>
#include <vector>

#include <glm/glm.hpp>

#if defined(__AVX512F__)
#include <immintrin.h>
#endif

#include "autodiff/vector_math.h"
#include "render/environment_map.h"
#include "render/equirect.h"
#include "render/radiance_query.h"
#include "render/spherical_gaussian.h"

namespace sl::render::detail {

struct Geometry {
  int64_t N, R, X, Y, Z, vox, H, W;
};

// The grid's log projection with its per-axis constants precomputed, in the query's precision:
// voxel = dims/2 ± k± · log1p(|d| / r0) for an offset d from the centre (vsg_volume.h).
template <class T>
struct LogProjection {
  int world_axis[3];
  T centre[3], inv_r0, r0, half_dims[3], k_pos[3], k_neg[3];
  explicit LogProjection(const VsgGrid& g) {
    const int map[3] = {0, 2, 1};  // X <- x, Y <- z, Z <- y
    inv_r0 = T(1.0 / g.log_scale_m);
    r0 = T(g.log_scale_m);
    for (int a = 0; a < 3; ++a) {
      const int w = map[a];
      world_axis[a] = w;
      centre[a] = T(g.center[w]);
      half_dims[a] = T(0.5 * double(g.dims[a]));
      k_pos[a] = T(0.5 * double(g.dims[a]) / std::log1p(g.extent_pos[w] / g.log_scale_m));
      k_neg[a] = T(0.5 * double(g.dims[a]) / std::log1p(g.extent_neg[w] / g.log_scale_m));
    }
  }
  // |dv/dt| along unit direction l at world position p: the voxel-space speed of the ray.
  T voxel_speed(const T p[3], const T l[3]) const {
    T s2 = 0;
    for (int a = 0; a < 3; ++a) {
      const T d = p[world_axis[a]] - centre[a];
      const T k = d >= 0 ? k_pos[a] : k_neg[a];
      const T s = k * l[world_axis[a]] / (r0 + std::abs(d));
      s2 += s * s;
    }
    return std::sqrt(s2);
  }
  void to_voxel(const T p[3], T v[3]) const {
    for (int a = 0; a < 3; ++a) {
      const T d = p[world_axis[a]] - centre[a];
      v[a] = d >= 0 ? half_dims[a] + k_pos[a] * std::log1p(d * inv_r0) : half_dims[a] - k_neg[a] * std::log1p(-d * inv_r0);
    }
  }
  // to_voxel() of the K points o + t_k·l at once (v: 3 per point, or in float with `planar`, axis
  // by axis: v[a·K + k]). In float, the logarithms go
  // through vm::log in one call (log(1 + x) for log1p(x): an absolute error of about 1e-7 voxel,
  // the same on every SIMD level); the exact volume marches of inference spent 8% of their time
  // in scalar log1pf. Forward and backward call this alike, so they still see the same samples.
  void to_voxel_all(const T o[3], const T l[3], const std::vector<double>& t, std::vector<T>& v,
                    bool planar = false) const {
    const size_t K = t.size();
    v.resize(3 * K);
    if constexpr (std::is_same_v<T, float>) {
      // Planar scratch [axis][sample], its pointers in locals: read through thread_local vectors
      // they were reloaded on every store, and the interleaved layout kept the loops scalar (a
      // sixth of RayMarcher's time under perf, KITTI insertion bench).
      thread_local std::vector<float> arg_buffer;
      thread_local std::vector<unsigned char> positive_buffer;
      if (arg_buffer.size() < 3 * K) {
        arg_buffer.resize(3 * K);
        positive_buffer.resize(3 * K);
      }
      float* const arg = arg_buffer.data();
      unsigned char* const positive = positive_buffer.data();
      float* const out = v.data();
      const double* const tk = t.data();
      for (int a = 0; a < 3; ++a) {
        const int w = world_axis[a];
        const double ow = o[w], lw = l[w];
        const float ca = centre[a];
        float* const arg_a = arg + a * K;
        unsigned char* const positive_a = positive + a * K;
        for (size_t k = 0; k < K; ++k) {
          const float d = float(ow + tk[k] * lw) - ca;
          positive_a[k] = d >= 0;
          arg_a[k] = 1.0f + std::abs(d) * inv_r0;
        }
      }
      vm::log(arg, arg, int64_t(3 * K));
      const size_t stride = planar ? 1 : 3;
      for (int a = 0; a < 3; ++a) {
        const float h = half_dims[a], kp = k_pos[a], kn = k_neg[a];
        const float* const log_a = arg + a * K;
        const unsigned char* const positive_a = positive + a * K;
        float* const out_a = planar ? out + a * K : out + a;
        for (size_t k = 0; k < K; ++k) {
          const float up = h + kp * log_a[k], down = h - kn * log_a[k];
          out_a[stride * k] = positive_a[k] ? up : down;
        }
      }
    } else {
      for (size_t k = 0; k < K; ++k) {
        const T pw[3] = {T(o[0] + t[k] * l[0]), T(o[1] + t[k] * l[1]), T(o[2] + t[k] * l[2])};
        to_voxel(pw, &v[3 * k]);
      }
    }
  }
};

template <class T>
struct Tap {
  int64_t voxel;
  T w;
};

// The samples one ray keeps after pruning, recomputed identically in forward and backward.
template <class T>
struct RayMarch {
  bool valid = false;       // finite, non-zero direction
  bool terminated = false;  // stopped by transmittance: no sky term
  T dir[3];                 // unit l
  T env[3];                 // L_env(l)
  EnvTaps env_taps;
  std::vector<T> alpha, t, g;           // per sample; g has 3 per sample
  std::vector<Tap<T>> taps;             // taps_per_sample per sample
  std::vector<double> tk, cumulative;   // sample distances and their arc-length table (scratch)
  std::vector<T> voxel;                 // the samples' voxel coordinates, 3 each (scratch)
  std::vector<int64_t> nearest;         // nearest lookup: each sample's voxel (scratch)
  std::vector<T> nearest_alpha;         // and its α (scratch)
  int taps_per_sample = 1;
  int64_t considered = 0;               // samples inside the grid before pruning
  size_t kept = 0;                      // samples kept: the first `kept` of alpha, t, g (3 each), taps
  size_t count() const { return kept; }
};

template <class T>
sg::Lobe<T> lobe_at(const T* vsg, int64_t vox, int64_t v) {
  sg::Lobe<T> L;
  for (int i = 0; i < 3; ++i) {
    L.c[i] = vsg[i * vox + v];
    L.mu[i] = vsg[(3 + i) * vox + v];
  }
  L.sharpness = vsg[6 * vox + v];
  return L;
}

// The volume as march() reads it. The op's tensors are channel planes [8][X·Y·Z]: one sample
// touches 8 cache lines of a 2 MB volume (64×64×16).
template <class T>
struct PlanarVolume {
  const T* vsg;
  int64_t vox;
  T alpha(int64_t v) const { return vsg[7 * vox + v]; }
  T colour(int64_t v, int c) const { return vsg[c * vox + v]; }
  sg::Lobe<T> lobe(int64_t v) const { return lobe_at(vsg, vox, v); }
  T exponent(int64_t v, const T dir[3]) const { return sg::exponent(lobe_at(vsg, vox, v), dir); }
};

// RayMarcher's copy: one 32-byte record per voxel (half a cache line) with the lobe's axis
// already normalised (sg::unit_axis), so a sample reads one line and skips a square root and
// three divisions. The values and the operations are PlanarVolume's: the same bits.
struct VoxelRecord {
  float c[3], muhat[3], sharpness, alpha;
};
struct InterleavedVolume {
  const VoxelRecord* voxel;
  float alpha(int64_t v) const { return voxel[v].alpha; }
  float colour(int64_t v, int c) const { return voxel[v].c[c]; }
  float exponent(int64_t v, const float dir[3]) const {
    return sg::unit_axis_exponent(voxel[v].muhat, voxel[v].sharpness, dir);
  }
};

// The K sample distances along a ray clipped to [t0, t1] (see the header's "Samples").
template <class T>
void sample_distances(const LogProjection<T>& proj, const RadianceQueryOptions& opt, const glm::dvec3& origin,
                      const glm::dvec3& dir, double t0, double t1, std::vector<double>& tk,
                      std::vector<double>& cumulative) {
  const int K = opt.samples;
  tk.resize(K);
  for (int k = 0; k < K; ++k) tk[k] = t0 + (k + 0.5) * (t1 - t0) / K;
  if (opt.spacing != SampleSpacing::kGrid || !(t1 > t0)) return;
  const int M = 4 * K;
  const double h = (t1 - t0) / M;
  const T l[3] = {T(dir.x), T(dir.y), T(dir.z)};
  auto speed = [&](double t) {
    const T p[3] = {T(origin.x + t * dir.x), T(origin.y + t * dir.y), T(origin.z + t * dir.z)};
    return double(proj.voxel_speed(p, l));
  };
  cumulative.resize(M + 1);
  cumulative[0] = 0.0;
  double prev = speed(t0);
  for (int j = 1; j <= M; ++j) {
    const double cur = speed(t0 + j * h);
    cumulative[j] = cumulative[j - 1] + 0.5 * h * (prev + cur);
    prev = cur;
  }
  const double total = cumulative[M];
  if (!(total > 0.0) || !std::isfinite(total)) return;  // keep the metric spacing
  int j = 0;
  for (int k = 0; k < K; ++k) {
    const double target = (k + 0.5) / K * total;
    while (j < M - 1 && cumulative[j + 1] < target) ++j;
    const double seg = cumulative[j + 1] - cumulative[j];
    const double f = seg > 0.0 ? std::clamp((target - cumulative[j]) / seg, 0.0, 1.0) : 0.5;
    tk[k] = t0 + (j + f) * h;
  }
}

// Nearest lookup's voxel of each of K samples from their planar voxel coordinates v[a·K + k]:
// clamp(⌊v⌋, 0, dim − 1) per axis, then (x·Y + y)·Z + z. The float → int64 conversion is the
// hardware's truncation, which gives 0x8000000000000000 for NaN, ±∞ and |v| ≥ 2^63 (the clamp
// makes that 0), scalar (cvttss2si) and in lanes (cvttps2qq) alike, so both paths give the same
// indices for every input (NearestVoxels.LanesEqualTheScalarLoop). The scalar loop was half of
// march_prefix's time under perf on an Intel Xeon (rounding and conversions share one port there).
inline void nearest_voxels_scalar(const float* v, int K, const int64_t dims[3], int64_t* out, int begin = 0) {
  for (int k = begin; k < K; ++k) {
    int64_t idx[3];
    for (int a = 0; a < 3; ++a) idx[a] = std::clamp<int64_t>(int64_t(std::floor(v[a * K + k])), 0, dims[a] - 1);
    out[k] = (idx[0] * dims[1] + idx[1]) * dims[2] + idx[2];
  }
}

inline void nearest_voxels(const float* v, int K, const int64_t dims[3], int64_t* out) {
  int k = 0;
#if defined(__AVX512F__) && defined(__AVX512DQ__) && defined(__AVX512VL__)
  const __m512i zero = _mm512_setzero_si512(), y = _mm512_set1_epi64(dims[1]), z = _mm512_set1_epi64(dims[2]);
  const __m512i top[3] = {_mm512_set1_epi64(dims[0] - 1), _mm512_set1_epi64(dims[1] - 1), _mm512_set1_epi64(dims[2] - 1)};
  for (; k + 8 <= K; k += 8) {
    __m512i idx[3];
    for (int a = 0; a < 3; ++a) {
      const __m256 f = _mm256_roundscale_ps(_mm256_loadu_ps(v + a * K + k), _MM_FROUND_TO_NEG_INF | _MM_FROUND_NO_EXC);
      idx[a] = _mm512_min_epi64(_mm512_max_epi64(_mm512_cvttps_epi64(f), zero), top[a]);
    }
    const __m512i xy = _mm512_add_epi64(_mm512_mullo_epi64(idx[0], y), idx[1]);
    _mm512_storeu_si512(out + k, _mm512_add_epi64(_mm512_mullo_epi64(xy, z), idx[2]));
  }
#endif
  nearest_voxels_scalar(v, K, dims, out, k);
}

// The part of march() before any sample is read: the ray's validity, L_env(l) and the
// transmittance `stop` that ends the march, the clip to the grid, the K sample distances and
// voxel coordinates, and with nearest lookup each sample's voxel (m.nearest). Returns false when
// the march has no samples (m.valid says whether the ray was valid at all).
// L_env's panorama coordinates: float, equirect::direction_to_unit(l) (the inner loops' form,
// within 1e-9 of libm's asin and atan2, which were 2.7% of the KITTI insertion bench here), or
// `unit` when the caller converted a batch of rays (directions_to_units: the same bits); float64
// (gradient checks) keeps libm's.
template <class T>
bool march_prefix(const Geometry& geo, const VsgGrid& grid, const LogProjection<T>& proj,
                  const RadianceQueryOptions& opt, const T* env, const T* o, const T* l, RayMarch<T>& m, T& stop,
                  const equirect::UV* unit = nullptr) {
  m.kept = 0;
  m.terminated = false;
  m.considered = 0;
  m.taps_per_sample = opt.trilinear ? 8 : 1;
  const T len = std::sqrt(l[0] * l[0] + l[1] * l[1] + l[2] * l[2]);
  m.valid = std::isfinite(len) && len > 0 && std::isfinite(o[0]) && std::isfinite(o[1]) && std::isfinite(o[2]);
  if (!m.valid) return false;
  for (int i = 0; i < 3; ++i) m.dir[i] = l[i] / len;
  if constexpr (std::is_same_v<T, float>)
    m.env_taps = env_bilinear_taps_unit(unit ? *unit : equirect::direction_to_unit(l[0], l[1], l[2]), int(geo.W), int(geo.H));
  else
    m.env_taps = env_bilinear_taps(m.dir[0], m.dir[1], m.dir[2], int(geo.W), int(geo.H));
  T env_max = 0;
  for (int c = 0; c < 3; ++c) {
    double v = 0;
    for (int k = 0; k < 4; ++k) v += m.env_taps.weight[k] * env[c * geo.H * geo.W + m.env_taps.index[k]];
    m.env[c] = T(v);
    env_max = std::max(env_max, m.env[c]);
  }
  const glm::dvec3 origin(o[0], o[1], o[2]), dir(m.dir[0], m.dir[1], m.dir[2]);
  double t0, t1;
  if (!grid.clip_ray(origin, dir, t0, t1)) return false;
  const int64_t dims[3] = {geo.X, geo.Y, geo.Z};
  stop = T(opt.min_transmittance) / std::max(T(1), env_max);
  sample_distances(proj, opt, origin, dir, t0, t1, m.tk, m.cumulative);
  // Float with nearest lookup: the coordinates axis by axis, for nearest_voxels' lanes (march()
  // reads m.voxel only for trilinear lookup).
  constexpr bool kFloat = std::is_same_v<T, float>;
  proj.to_voxel_all(o, m.dir, m.tk, m.voxel, kFloat && !opt.trilinear);
  const int K = opt.samples;
  if (!opt.trilinear) {
    if (m.nearest.size() < size_t(K)) {
      m.nearest.resize(size_t(K));
      m.nearest_alpha.resize(size_t(K));
    }
    int64_t* const nearest = m.nearest.data();
    const T* const voxel = m.voxel.data();
    if constexpr (kFloat) {
      nearest_voxels(voxel, K, dims, nearest);
    } else {
      for (int k = 0; k < K; ++k) {
        const T* p = &voxel[size_t(3 * k)];
        int64_t idx[3];
        for (int a = 0; a < 3; ++a) idx[a] = std::clamp<int64_t>(int64_t(std::floor(p[a])), 0, dims[a] - 1);
        nearest[k] = (idx[0] * geo.Y + idx[1]) * geo.Z + idx[2];
      }
    }
  }
  return true;
}

template <class T, class Volume>
void march(const Geometry& geo, const VsgGrid& grid, const LogProjection<T>& proj, const RadianceQueryOptions& opt,
           const Volume& vol, const T* env, const T* o, const T* l, RayMarch<T>& m) {
  constexpr bool kBatchedLobes = std::is_same_v<T, float>;
  T stop;
  if (!march_prefix(geo, grid, proj, opt, env, o, l, m, stop)) return;
  const T v[3] = {-m.dir[0], -m.dir[1], -m.dir[2]};  // lobes are seen from x: G(−l)
  const T empty_alpha = T(opt.empty_alpha);
  const bool prune = opt.prune;
  T tau = 1;
  const bool grid_spacing = opt.spacing == SampleSpacing::kGrid;
  int64_t last_voxel = -1;
  // The kept samples are written in place into scratch of K (grown, never shrunk) and counted:
  // per-sample push_backs reloaded the vectors' ends on every store, and copying a tap built on
  // the stack stalled on store forwarding (perf, KITTI insertion bench).
  const int K = opt.samples, nt = m.taps_per_sample;
  if (m.alpha.size() < size_t(K)) {
    m.alpha.resize(size_t(K));
    m.t.resize(size_t(K));
    m.g.resize(size_t(3 * K));
  }
  if (m.taps.size() < size_t(K) * size_t(nt)) m.taps.resize(size_t(K) * size_t(nt));
  T* const keep_alpha = m.alpha.data();
  T* const keep_t = m.t.data();
  T* const keep_g = m.g.data();
  Tap<T>* const keep_taps = m.taps.data();
  const T* const voxel = m.voxel.data();
  const double* const tks = m.tk.data();
  const int64_t dims[3] = {geo.X, geo.Y, geo.Z};
  // Nearest lookup: every sample's α first (march_prefix found the voxels), in a loop without a
  // branch on α, so the volume's cache misses overlap instead of each stalling the sequential
  // loop below (a quarter of RayMarcher's time sat on that load under perf, KITTI insertion bench).
  if (!opt.trilinear) {
    const int64_t* const nearest = m.nearest.data();
    T* const nearest_alpha = m.nearest_alpha.data();
    for (int k = 0; k < K; ++k) nearest_alpha[k] = vol.alpha(nearest[k]);
  }
  int kept = 0;
  for (int k = 0; k < K; ++k) {
    const double tk = tks[k];
    const T* p = &voxel[size_t(3 * k)];
    ++m.considered;
    Tap<T>* const taps = keep_taps + size_t(kept) * size_t(nt);  // overwritten if not kept
    T alpha = 0;
    if (!opt.trilinear) {
      const int64_t nearest = m.nearest[size_t(k)];
      // Grid spacing composites a voxel once per crossing: a second sample in the voxel the
      // previous one read would apply its α twice.
      if (grid_spacing && nearest == last_voxel) continue;
      last_voxel = nearest;
      taps[0].voxel = nearest;
      taps[0].w = T(1);
      alpha += T(1) * m.nearest_alpha[size_t(k)];
    } else {
      int64_t i0[3], i1[3];
      T fr[3];
      for (int a = 0; a < 3; ++a) {
        const double f = double(p[a]) - 0.5, fl = std::floor(f);
        fr[a] = T(f - fl);
        i0[a] = std::clamp<int64_t>(int64_t(fl), 0, dims[a] - 1);
        i1[a] = std::clamp<int64_t>(int64_t(fl) + 1, 0, dims[a] - 1);
      }
      for (int c = 0; c < 8; ++c) {
        const int64_t x = (c & 1) ? i1[0] : i0[0], y = (c & 2) ? i1[1] : i0[1], z = (c & 4) ? i1[2] : i0[2];
        const T w = ((c & 1) ? fr[0] : 1 - fr[0]) * ((c & 2) ? fr[1] : 1 - fr[1]) * ((c & 4) ? fr[2] : 1 - fr[2]);
        taps[c].voxel = (x * geo.Y + y) * geo.Z + z;
        taps[c].w = w;
      }
      for (int j = 0; j < 8; ++j) alpha += taps[j].w * vol.alpha(taps[j].voxel);
    }
    if (prune && alpha < empty_alpha) continue;
    T g[3] = {0, 0, 0};
    if constexpr (!kBatchedLobes) {
      for (int j = 0; j < nt; ++j) {
        const auto e = sg::eval(vol.lobe(taps[j].voxel), v);
        for (int c = 0; c < 3; ++c) g[c] += taps[j].w * e.value[c];
      }
    }
    keep_alpha[kept] = alpha;
    keep_t[kept] = T(tk);
    for (int c = 0; c < 3; ++c) keep_g[3 * kept + c] = g[c];
    ++kept;
    tau *= (1 - alpha);
    if (prune && tau < stop) {
      m.terminated = true;
      break;
    }
  }
  m.kept = size_t(kept);
  if constexpr (kBatchedLobes) {
    // The kept samples' lobes: which samples are kept and where the march stops depend on α
    // alone, so the exponentials of all their taps go through one vm::exp call (≤ 1 ulp from
    // std::exp, the same on every SIMD level; the backward's sg::eval differs from it by that).
    thread_local std::vector<float> arg_buffer;
    const size_t n = size_t(kept) * size_t(nt);
    if (arg_buffer.size() < n) arg_buffer.resize(n);
    float* const arg = arg_buffer.data();
    for (size_t i = 0; i < n; ++i) arg[i] = vol.exponent(keep_taps[i].voxel, v);
    vm::exp(arg, arg, int64_t(n));
    // Tap i belongs to sample i / nt, nt = 1 or 8: a shift (a 64-bit division per tap showed
    // under perf).
    const int shift = nt == 8 ? 3 : 0;
    for (size_t i = 0; i < n; ++i) {
      const Tap<T>& tap = keep_taps[i];
      T* const g = keep_g + 3 * (i >> shift);
      for (int ch = 0; ch < 3; ++ch) g[ch] += tap.w * (vol.colour(tap.voxel, ch) * arg[i]);
    }
  }
}

// Eq. 1's sums over one marched ray: radiance, τ_K and depth (the forward of the op, and
// RayMarcher's).
template <class T>
void composite(const RayMarch<T>& m, T out[3], T& tr, T& d) {
  out[0] = out[1] = out[2] = 0;
  tr = 1;
  d = 0;
  if (!m.valid) return;
  // In locals: stores through `out` may alias the samples, and reloading them per sample cost
  // more than the sums.
  T r0 = 0, r1 = 0, r2 = 0, tau = 1, depth = 0;
  const T* alpha = m.alpha.data();
  const T* t = m.t.data();
  const T* g = m.g.data();
  const size_t K = m.count();
  for (size_t k = 0; k < K; ++k) {
    const T w = tau * alpha[k];
    r0 += w * g[3 * k];
    r1 += w * g[3 * k + 1];
    r2 += w * g[3 * k + 2];
    depth += w * t[k];
    tau *= 1 - alpha[k];
  }
  if (!m.terminated) {
    r0 += tau * m.env[0];
    r1 += tau * m.env[1];
    r2 += tau * m.env[2];
  }
  out[0] = r0;
  out[1] = r1;
  out[2] = r2;
  tr = tau;
  d = depth;
}

}  // namespace sl::render::detail
