// radiance_query(): Eq. 1 as one tape op over a batch of rays (see radiance_query.h); the march
// itself is render/radiance_march.h, shared with RayMarcher (ray_marcher.cpp).
#include "render/radiance_query.h"

#include <algorithm>
#include <atomic>
#include <cmath>

#include "autodiff/ops.h"
#include "render/environment_map.h"
#include "render/radiance_march.h"
#include "render/spherical_gaussian.h"
#include "util/parallel.h"

namespace sl::render {
namespace {

using namespace detail;

constexpr int kGradBuffers = 4;  // fixed, so the summation order never depends on threads

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
