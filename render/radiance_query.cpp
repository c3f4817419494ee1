#include "render/radiance_query.h"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstddef>
#include <type_traits>

#if defined(__AVX512F__)
#include <immintrin.h>
#endif

#include "autodiff/ops.h"
#include "autodiff/vector_math.h"
#include "render/environment_map.h"
#include "render/spherical_gaussian.h"
#include "util/parallel.h"

namespace sl::render {
namespace {

constexpr int kGradBuffers = 4;  // fixed, so the summation order never depends on threads

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
  // to_voxel() of the K points o + t_k·l at once (v: 3 per point). In float, the logarithms go
  // through vm::log in one call (log(1 + x) for log1p(x): an absolute error of about 1e-7 voxel,
  // the same on every SIMD level); the exact volume marches of inference spent 8% of their time
  // in scalar log1pf. Forward and backward call this alike, so they still see the same samples.
  void to_voxel_all(const T o[3], const T l[3], const std::vector<double>& t, std::vector<T>& v) const {
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
      for (int a = 0; a < 3; ++a) {
        const float h = half_dims[a], kp = k_pos[a], kn = k_neg[a];
        const float* const log_a = arg + a * K;
        const unsigned char* const positive_a = positive + a * K;
        for (size_t k = 0; k < K; ++k) {
          const float up = h + kp * log_a[k], down = h - kn * log_a[k];
          out[3 * k + size_t(a)] = positive_a[k] ? up : down;
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

// The part of march() before any sample is read: the ray's validity, L_env(l) and the
// transmittance `stop` that ends the march, the clip to the grid, the K sample distances and
// voxel coordinates, and with nearest lookup each sample's voxel (m.nearest). Returns false when
// the march has no samples (m.valid says whether the ray was valid at all).
template <class T>
bool march_prefix(const Geometry& geo, const VsgGrid& grid, const LogProjection<T>& proj,
                  const RadianceQueryOptions& opt, const T* env, const T* o, const T* l, RayMarch<T>& m, T& stop) {
  m.kept = 0;
  m.terminated = false;
  m.considered = 0;
  m.taps_per_sample = opt.trilinear ? 8 : 1;
  const T len = std::sqrt(l[0] * l[0] + l[1] * l[1] + l[2] * l[2]);
  m.valid = std::isfinite(len) && len > 0 && std::isfinite(o[0]) && std::isfinite(o[1]) && std::isfinite(o[2]);
  if (!m.valid) return false;
  for (int i = 0; i < 3; ++i) m.dir[i] = l[i] / len;
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
  proj.to_voxel_all(o, m.dir, m.tk, m.voxel);
  const int K = opt.samples;
  if (!opt.trilinear) {
    if (m.nearest.size() < size_t(K)) {
      m.nearest.resize(size_t(K));
      m.nearest_alpha.resize(size_t(K));
    }
    int64_t* const nearest = m.nearest.data();
    const T* const voxel = m.voxel.data();
    for (int k = 0; k < K; ++k) {
      const T* p = &voxel[size_t(3 * k)];
      int64_t idx[3];
      for (int a = 0; a < 3; ++a) idx[a] = std::clamp<int64_t>(int64_t(std::floor(p[a])), 0, dims[a] - 1);
      nearest[k] = (idx[0] * geo.Y + idx[1]) * geo.Z + idx[2];
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

class RadianceQueryOp : public Function {
 public:
  RadianceQueryOp(const VsgGrid& grid, const RadianceQueryOptions& opt, RadianceQueryStats* stats)
      : grid_(grid), opt_(opt), stats_(stats) {}

  std::string name() const override { return "radiance_query"; }

  TensorList forward(const TensorList& in) override {
    vsg_ = in[0].detach().contiguous();
    env_ = in[1].detach().contiguous();
    origins_ = in[2].detach().contiguous();
    dirs_ = in[3].detach().contiguous();
    geo_ = {vsg_.size(0), origins_.size(1), vsg_.size(2), vsg_.size(3), vsg_.size(4), 0, env_.size(2), env_.size(3)};
    geo_.vox = geo_.X * geo_.Y * geo_.Z;
    Tensor radiance = Tensor::empty({geo_.N, geo_.R, 3}, vsg_.dtype());
    Tensor tau = Tensor::empty({geo_.N, geo_.R}, vsg_.dtype());
    Tensor depth = Tensor::empty({geo_.N, geo_.R}, vsg_.dtype());
    std::atomic<int64_t> total{0}, evaluated{0}, terminated{0};
    SL_DISPATCH_FLOAT(vsg_.dtype(), "radiance_query", [&] {
      using T = scalar_t;
      const LogProjection<T> proj(grid_);
      parallel_for(geo_.N * geo_.R, 64, [&](int64_t b, int64_t e) {
        RayMarch<T> m;
        int64_t n_total = 0, n_eval = 0, n_term = 0;
        for (int64_t r = b; r < e; ++r) {
          const int64_t n = r / geo_.R;
          march(geo_, grid_, proj, opt_, PlanarVolume<T>{vsg_.data<T>() + n * 8 * geo_.vox, geo_.vox},
                env_.data<T>() + n * 3 * geo_.H * geo_.W,
                origins_.data<T>() + 3 * r, dirs_.data<T>() + 3 * r, m);
          T out[3], tr, d;
          composite(m, out, tr, d);
          for (int c = 0; c < 3; ++c) radiance.data<T>()[3 * r + c] = out[c];
          tau.data<T>()[r] = tr;
          depth.data<T>()[r] = d;
          n_total += m.considered;
          n_eval += int64_t(m.count());
          n_term += m.terminated ? 1 : 0;
        }
        total += n_total;
        evaluated += n_eval;
        terminated += n_term;
      });
    });
    if (stats_) {
      stats_->rays += geo_.N * geo_.R;
      stats_->samples_total += total.load();
      stats_->samples_evaluated += evaluated.load();
      stats_->rays_terminated += terminated.load();
    }
    return {radiance, tau, depth};
  }

  TensorList backward(const TensorList& grads) override {
    const Tensor gR = grads[0].contiguous(), gT = grads[1].contiguous(), gD = grads[2].contiguous();
    const int64_t rays = geo_.N * geo_.R;
    const int64_t vsg_size = geo_.N * 8 * geo_.vox, env_size = geo_.N * 3 * geo_.H * geo_.W;
    Tensor g_vsg = Tensor::zeros(vsg_.shape(), vsg_.dtype());
    Tensor g_env = Tensor::zeros(env_.shape(), env_.dtype());
    SL_DISPATCH_FLOAT(vsg_.dtype(), "radiance_query", [&] {
      using T = scalar_t;
      std::vector<std::vector<T>> buf_vsg(kGradBuffers), buf_env(kGradBuffers);
      const int64_t chunk = (rays + kGradBuffers - 1) / kGradBuffers;
      parallel_for(kGradBuffers, 1, [&](int64_t b0, int64_t b1) {
        for (int64_t b = b0; b < b1; ++b) {
          const int64_t r0 = b * chunk, r1 = std::min(rays, r0 + chunk);
          if (r0 >= r1) continue;
          buf_vsg[b].assign(size_t(vsg_size), T(0));
          buf_env[b].assign(size_t(env_size), T(0));
          RayMarch<T> m;
          std::vector<T> tau_before;
          for (int64_t r = r0; r < r1; ++r) backward_ray<T>(r, gR, gT, gD, m, tau_before, buf_vsg[b], buf_env[b]);
        }
      });
      // Sum the chunk buffers in chunk order.
      T* pv = g_vsg.data<T>();
      T* pe = g_env.data<T>();
      for (int b = 0; b < kGradBuffers; ++b) {
        if (buf_vsg[b].empty()) continue;
        const T* sv = buf_vsg[b].data();
        const T* se = buf_env[b].data();
        parallel_for(vsg_size, 65536, [&](int64_t i0, int64_t i1) {
          for (int64_t i = i0; i < i1; ++i) pv[i] += sv[i];
        });
        for (int64_t i = 0; i < env_size; ++i) pe[i] += se[i];
      }
    });
    return {g_vsg, g_env, Tensor(), Tensor()};
  }

 private:
  template <class T>
  void backward_ray(int64_t r, const Tensor& gR, const Tensor& gT, const Tensor& gD, RayMarch<T>& m,
                    std::vector<T>& tau_before, std::vector<T>& bv, std::vector<T>& be) const {
    const int64_t n = r / geo_.R;
    const T* vsg = vsg_.data<T>() + n * 8 * geo_.vox;
    const LogProjection<T> proj(grid_);
    march(geo_, grid_, proj, opt_, PlanarVolume<T>{vsg, geo_.vox}, env_.data<T>() + n * 3 * geo_.H * geo_.W,
          origins_.data<T>() + 3 * r,
          dirs_.data<T>() + 3 * r, m);
    if (!m.valid) return;
    const T* gr = gR.data<T>() + 3 * r;
    const T gt = gT.data<T>()[r], gd = gD.data<T>()[r];
    const size_t K = m.count();
    tau_before.resize(K + 1);
    tau_before[0] = 1;
    for (size_t k = 0; k < K; ++k) tau_before[k + 1] = tau_before[k] * (1 - m.alpha[k]);
    // Sky term: ∂L/∂L_env = τ_K.
    if (!m.terminated) {
      T* env_grad = be.data() + n * 3 * geo_.H * geo_.W;
      for (int c = 0; c < 3; ++c)
        for (int j = 0; j < 4; ++j)
          env_grad[c * geo_.H * geo_.W + m.env_taps.index[j]] += T(m.env_taps.weight[j]) * gr[c] * tau_before[K];
    }
    // Back to front: B is the radiance seen just behind sample k, BD the same for depth, P the
    // transmittance from behind sample k to the end.
    T B[3];
    for (int c = 0; c < 3; ++c) B[c] = m.terminated ? T(0) : m.env[c];
    T BD = 0, P = 1;
    T* gv = bv.data() + n * 8 * geo_.vox;
    const T v[3] = {-m.dir[0], -m.dir[1], -m.dir[2]};
    const int nt = m.taps_per_sample;
    for (size_t kk = K; kk-- > 0;) {
      const T a = m.alpha[kk], tb = tau_before[kk];
      T g_alpha = gd * tb * (m.t[kk] - BD) - gt * tb * P;
      T g_lobe[3];
      for (int c = 0; c < 3; ++c) {
        g_alpha += gr[c] * tb * (m.g[3 * kk + c] - B[c]);
        g_lobe[c] = gr[c] * tb * a;
      }
      for (int j = 0; j < nt; ++j) {
        const Tap<T>& tap = m.taps[kk * nt + j];
        gv[7 * geo_.vox + tap.voxel] += tap.w * g_alpha;
        const sg::Lobe<T> lobe = lobe_at(vsg, geo_.vox, tap.voxel);
        const auto e = sg::eval(lobe, v);
        const T up[3] = {tap.w * g_lobe[0], tap.w * g_lobe[1], tap.w * g_lobe[2]};
        T gc[3] = {0, 0, 0}, gmu[3] = {0, 0, 0}, gs = 0;
        sg::backward(lobe, v, e, up, gc, gmu, gs);
        for (int c = 0; c < 3; ++c) {
          gv[c * geo_.vox + tap.voxel] += gc[c];
          gv[(3 + c) * geo_.vox + tap.voxel] += gmu[c];
        }
        gv[6 * geo_.vox + tap.voxel] += gs;
      }
      for (int c = 0; c < 3; ++c) B[c] = a * m.g[3 * kk + c] + (1 - a) * B[c];
      BD = a * m.t[kk] + (1 - a) * BD;
      P *= 1 - a;
    }
  }

  VsgGrid grid_;
  RadianceQueryOptions opt_;
  RadianceQueryStats* stats_;
  Tensor vsg_, env_, origins_, dirs_;
  Geometry geo_{};
};

}  // namespace

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
  const Voxels& vx = *voxels_;
  const int64_t vox = vx.X * vx.Y * vx.Z;
#if defined(__AVX512F__)
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
// voxels) is march_prefix(), as in march(); then per sample k, all lanes at once: α from the
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
    __mmask16 live = 0;
    for (int j = 0; j < kLanes; ++j) {
      const int64_t i = g0 + j;
      float s = 0;
      if (j < lanes && march_prefix(geo, grid_, *proj_, opt_, env, origins + 3 * i, dirs + 3 * i, m, s)) {
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

SampleSpacing parse_sample_spacing(const std::string& name) {
  if (name == "metric") return SampleSpacing::kMetric;
  if (name == "grid") return SampleSpacing::kGrid;
  throw Error("sample spacing '" + name + "' is not one of: metric, grid");
}

const char* sample_spacing_name(SampleSpacing spacing) {
  return spacing == SampleSpacing::kGrid ? "grid" : "metric";
}

RadianceQueryResult radiance_query(const Tensor& vsg, const Tensor& env, const Tensor& origins,
                                   const Tensor& directions, const VsgGrid& grid, const RadianceQueryOptions& options,
                                   RadianceQueryStats* stats) {
  grid.validate();
  SL_CHECK(options.samples >= 1, "radiance_query: samples = ", options.samples, " must be >= 1");
  const bool batched = vsg.dim() == 5;
  SL_CHECK(vsg.dim() == (batched ? 5 : 4) && vsg.size(batched ? 1 : 0) == 8,
           "radiance_query: vsg must be [N, 8, X, Y, Z] or [8, X, Y, Z], got ", vsg.describe());
  SL_CHECK(env.dim() == (batched ? 4 : 3) && env.size(batched ? 1 : 0) == 3,
           "radiance_query: env must be [N, 3, H, W] or [3, H, W] to match vsg ", vsg.describe(), ", got ",
           env.describe());
  SL_CHECK(origins.shape() == directions.shape() && origins.dim() == (batched ? 3 : 2) && origins.size(-1) == 3,
           "radiance_query: origins ", origins.describe(), " and directions ", directions.describe(),
           " must both be [N, R, 3] (or [R, 3])");
  for (const Tensor* t : {&env, &origins, &directions})
    SL_CHECK(t->dtype() == vsg.dtype(), "radiance_query: dtypes differ: vsg ", vsg.describe(), ", got ", t->describe());
  const Tensor v = batched ? vsg : unsqueeze(vsg, 0);
  const Tensor e = batched ? env : unsqueeze(env, 0);
  const Tensor o = batched ? origins : unsqueeze(origins, 0);
  const Tensor d = batched ? directions : unsqueeze(directions, 0);
  SL_CHECK(e.size(0) == v.size(0) && o.size(0) == v.size(0), "radiance_query: batch sizes differ: vsg ",
           vsg.describe(), ", env ", env.describe(), ", origins ", origins.describe());
  SL_CHECK(v.size(2) == grid.dims[0] && v.size(3) == grid.dims[1] && v.size(4) == grid.dims[2],
           "radiance_query: vsg ", vsg.describe(), " does not match the grid dims [", grid.dims[0], ", ",
           grid.dims[1], ", ", grid.dims[2], "]");
  TensorList out = apply(std::make_shared<RadianceQueryOp>(grid, options, stats), {v, e, o, d});
  if (batched) return {out[0], out[1], out[2]};
  return {squeeze(out[0], 0), squeeze(out[1], 0), squeeze(out[2], 0)};
}

}  // namespace sl::render
