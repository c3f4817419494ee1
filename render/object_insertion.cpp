// insert_objects(): Sec 3.3 — composes the foreground (Eq. 2, insertion_foreground.cpp) and the
// ratio shadows (Eq. 3-4, insertion_shadows.cpp) and composites them.
// Geometry, materials and sampling are constants; the lighting (env, vsg) is on the tape. All
// light and shadow rays go through ONE radiance query; two segment reductions and a few
// gather/scatter ops assemble the image.
#include "render/object_insertion.h"

#include <algorithm>
#include <cmath>

#include "autodiff/ops.h"
#include "autodiff/tape.h"
#include "render/disney_brdf.h"
#include "render/environment_map.h"
#include "render/equirect.h"
#include "render/insertion_foreground.h"
#include "render/insertion_ops.h"
#include "render/insertion_shadows.h"
#include "render/sampling.h"
#include "util/math.h"
#include "util/parallel.h"
#include "util/random.h"

namespace sl::render {
namespace {
using insertion::QueryRays;

// The radiance cache of the header: V = Σ τ α G and τ_K per probe and direction, read
// trilinearly × bilinearly; L_env is looked up exactly per ray.
class RadianceCache {
 public:
  // Probes over the origins of rays [begin, end), at most max_xz per horizontal axis and
  // max_y vertically.
  RadianceCache(const InsertionInputs& in, const InsertionOptions& opt, const EnvironmentMap& env_map,
                const QueryRays& rays, int64_t begin, int64_t end, int max_xz, int max_y)
      : env_map_(env_map), H_(opt.cache_height), W_(opt.cache_width) {
    if (begin >= end) return;  // no rays read it
    glm::vec3 lo(1e30f), hi(-1e30f);
    for (int64_t r = begin; r < end; ++r) {
      const glm::vec3 o(rays.origin[size_t(3 * r)], rays.origin[size_t(3 * r + 1)], rays.origin[size_t(3 * r + 2)]);
      lo = glm::min(lo, o);
      hi = glm::max(hi, o);
    }
    lo_ = lo;
    for (int a = 0; a < 3; ++a) {
      const float ext = std::max(0.0f, hi[a] - lo[a]);
      n_[a] = std::clamp(int(std::ceil(ext / opt.cache_spacing_m)) + 1, 2, a == 1 ? max_y : max_xz);
      step_[a] = ext > 0 ? ext / float(n_[a] - 1) : 1.0f;
    }
    const int64_t D = int64_t(H_) * W_, P = int64_t(n_[0]) * n_[1] * n_[2];
    std::vector<float> o(size_t(3 * P * D)), d(size_t(3 * P * D));
    std::vector<glm::vec3> dirs(static_cast<size_t>(D));
    for (int64_t t = 0; t < D; ++t) {
      const equirect::Dir e = equirect::uv_to_direction(double(t % W_) + 0.5, double(t / W_) + 0.5, W_, H_);
      dirs[size_t(t)] = glm::vec3(float(e.x), float(e.y), float(e.z));
    }
    for (int64_t p = 0; p < P; ++p)
      for (int64_t t = 0; t < D; ++t)
        for (int c = 0; c < 3; ++c) {
          o[size_t(3 * (p * D + t) + c)] = probe(p)[c];
          d[size_t(3 * (p * D + t) + c)] = dirs[size_t(t)][c];
        }
    Tensor ot = Tensor::empty({P * D, 3}, DType::F32), dt = Tensor::empty({P * D, 3}, DType::F32);
    std::copy(o.begin(), o.end(), ot.data<float>());
    std::copy(d.begin(), d.end(), dt.data<float>());
    const RadianceQueryResult q = radiance_query(in.vsg.detach().to(DType::F32).contiguous(),
                                                 in.env.detach().to(DType::F32).contiguous(), ot, dt, in.grid, opt.query);
    const Tensor rad = q.radiance.contiguous(), tau = q.transmittance.contiguous();
    const float* rp = rad.data<float>();
    const float* tp = tau.data<float>();
    cache_.resize(size_t(4 * P * D));
    for (int64_t i = 0; i < P * D; ++i) {
      const glm::vec3 sky = env_map_.lookup(dirs[size_t(i % D)]);
      for (int c = 0; c < 3; ++c) cache_[size_t(4 * i + c)] = rp[3 * i + c] - tp[i] * sky[c];
      cache_[size_t(4 * i + 3)] = tp[i];
    }
  }

  glm::vec3 radiance(const float* origin, const float* dir) const {
    const glm::vec3 l(dir[0], dir[1], dir[2]);
    if (!(glm::dot(l, l) > 0.0f) || !all_finite(l)) return glm::vec3(0.0f);
    int i0[3];
    float f[3];
    for (int a = 0; a < 3; ++a) {
      const float x = std::clamp((origin[a] - lo_[a]) / step_[a], 0.0f, float(n_[a] - 1));
      i0[a] = std::min(int(x), n_[a] - 2);
      f[a] = x - float(i0[a]);
    }
    const equirect::UV unit = equirect::direction_to_uv(l.x, l.y, l.z, 1, 1);  // one atan2/asin for both maps
    const EnvTaps taps = env_bilinear_taps_unit(unit, W_, H_);
    const int64_t D = int64_t(H_) * W_;
    glm::vec4 acc(0.0f);
    for (int c = 0; c < 8; ++c) {
      const int ix = i0[0] + (c & 1), iy = i0[1] + ((c >> 1) & 1), iz = i0[2] + (c >> 2);
      const float wc = ((c & 1) ? f[0] : 1 - f[0]) * (((c >> 1) & 1) ? f[1] : 1 - f[1]) * ((c >> 2) ? f[2] : 1 - f[2]);
      if (wc == 0.0f) continue;
      const float* base = &cache_[size_t(4 * ((int64_t(iz) * n_[1] + iy) * n_[0] + ix) * D)];
      for (int k = 0; k < 4; ++k) {
        const float w = wc * float(taps.weight[k]);
        const float* e = base + 4 * taps.index[k];
        acc += w * glm::vec4(e[0], e[1], e[2], e[3]);
      }
    }
    return glm::vec3(acc) + acc.w * env_map_.lookup_unit(unit);
  }

 private:
  glm::vec3 probe(int64_t p) const {
    const int ix = int(p % n_[0]), iy = int(p / n_[0] % n_[1]), iz = int(p / (int64_t(n_[0]) * n_[1]));
    return lo_ + glm::vec3(float(ix) * step_[0], float(iy) * step_[1], float(iz) * step_[2]);
  }
  const EnvironmentMap& env_map_;
  int H_, W_;
  glm::vec3 lo_{0.0f};
  int n_[3] = {2, 2, 2};
  float step_[3] = {1, 1, 1};
  std::vector<float> cache_;  // [probe][direction][V rgb, τ]
};

void validate(const InsertionInputs& in, const InsertionOptions& opt) {
  const int W = in.camera.intrinsics().width, H = in.camera.intrinsics().height;
  SL_CHECK(in.background.dim() == 3 && in.background.size(0) == 3 && in.background.size(1) == H &&
               in.background.size(2) == W,
           "insert_objects: background ", in.background.describe(), " does not match the camera's ", W, "x", H);
  SL_CHECK(in.depth.dim() == 2 && in.depth.size(0) == H && in.depth.size(1) == W, "insert_objects: depth ",
           in.depth.describe(), " does not match the camera's ", W, "x", H, " image");
  SL_CHECK(in.env.dim() == 3 && in.env.size(0) == 3, "insert_objects: env must be [3, H, W], got ", in.env.describe());
  SL_CHECK(!in.vsg.defined() || in.vsg.dtype() == in.env.dtype(), "insert_objects: vsg ", in.vsg.describe(),
           " and env ", in.env.describe(), " differ in dtype");
  SL_CHECK(opt.aa_samples >= 1 && opt.light_samples >= 1 && opt.shadow_rays >= 1, "insert_objects: sample counts (aa ",
           opt.aa_samples, ", light ", opt.light_samples, ", shadow ", opt.shadow_rays, ") must be >= 1");
  SL_CHECK(opt.shadow_width >= 1 && opt.shadow_height >= 1, "insert_objects: shadow map ", opt.shadow_width, "x",
           opt.shadow_height, " is empty");
  SL_CHECK(opt.ambient >= 0 && opt.ambient <= 1, "insert_objects: ambient I_a = ", opt.ambient, " must be in [0, 1]");
  SL_CHECK(!opt.radiance_cache || (opt.cache_height >= 2 && opt.cache_width >= 2 && opt.cache_spacing_m > 0 &&
                                    opt.cache_max_xz >= 2 && opt.cache_max_y >= 2 && opt.cache_shadow_max_xz >= 2 &&
                                    opt.cache_shadow_max_y >= 2),
           "insert_objects: radiance cache ", opt.cache_width, "x", opt.cache_height, " with spacing ",
           opt.cache_spacing_m, " m (at most ", opt.cache_max_xz, "x", opt.cache_max_y, " probes) is invalid");
  SL_CHECK(!opt.radiance_cache || !grad_enabled() ||
               !(in.env.requires_grad() || (in.vsg.defined() && in.vsg.requires_grad())),
           "insert_objects: radiance_cache is for inference; gradients into env/vsg need exact queries");
}

Tensor as_tensor(const std::vector<float>& v, const Shape& shape, DType dt) {
  Tensor t = Tensor::empty(shape, DType::F32);
  std::copy(v.begin(), v.end(), t.data<float>());
  return t.to(dt);
}

}  // namespace

InsertionResult insert_objects(const InsertionInputs& in, const InsertionOptions& opt) {
  using namespace insertion;
  validate(in, opt);
  const DType dt = in.env.dtype();
  const int W = in.camera.intrinsics().width, H = in.camera.intrinsics().height;
  const int64_t HW = int64_t(W) * H;
  InsertionResult out;

  // One object: its own BVH, built once by place_object() and reused across calls.
  Mesh merged;
  std::shared_ptr<const Bvh> own;
  if (in.objects.size() == 1 && in.objects[0].bvh) {
    own = in.objects[0].bvh;
  } else {
    for (const PlacedObject& o : in.objects) merged.append(o.mesh);
    own = std::make_shared<const Bvh>(merged);
  }
  const Mesh& mesh = in.objects.size() == 1 && in.objects[0].bvh ? in.objects[0].mesh : merged;
  const Bvh& bvh = *own;
  const Tensor depth_t = in.depth.detach().to(DType::F64).contiguous();
  const double* depth = depth_t.data<double>();
  const EnvironmentMap env_map(in.env.detach());

  Foreground fg;
  Shadows sh;
  QueryRays rays;
  std::vector<GSample> gs;
  if (!bvh.empty()) {
    gs = gbuffer(in, opt, mesh, bvh, depth, fg, out.stats);
    // Eq. 2's N: fixed per sample, or a total ray budget spread over the visible samples (the
    // paper samples 5000 foreground rays in training).
    fg.light_samples = opt.foreground_rays > 0
                           ? int(std::max<int64_t>(1, opt.foreground_rays / std::max<int64_t>(1, int64_t(gs.size()))))
                           : opt.light_samples;
  } else {
    fg.coverage.assign(size_t(HW), 0.0f);
    fg.depth.assign(size_t(HW), 0.0f);
    fg.silhouette.assign(size_t(HW), 0.0f);
    out.stats.image_pixels_total = HW;
  }
  const int64_t fg_rays = int64_t(gs.size()) * fg.light_samples;
  if (!bvh.empty()) {
    rays.resize(fg_rays);
    trace_foreground(opt, bvh, env_map, gs, fg, rays);
    QueryRays shadow_rays;  // appended after the light rays
    trace_shadows(in, opt, bvh.bounds(), bvh, env_map, depth, sh, shadow_rays, out.stats);
    rays.origin.insert(rays.origin.end(), shadow_rays.origin.begin(), shadow_rays.origin.end());
    rays.dir.insert(rays.dir.end(), shadow_rays.dir.begin(), shadow_rays.dir.end());
  } else {
    fg.offsets = {0};
    sh.texel_depth.assign(size_t(opt.shadow_width) * opt.shadow_height, 0.0f);
    sh.offsets = {0};
    out.stats.shadow_pixels_total = int64_t(opt.shadow_width) * opt.shadow_height;
  }
  const int64_t sh_rays = rays.size() - fg_rays;
  out.stats.query_rays = rays.size();

  // ---- one radiance query for every light and shadow ray (Eq. 1)
  Tensor radiance = Tensor::zeros({0, 3}, dt);
  if (rays.size() > 0 && in.vsg.defined() && opt.radiance_cache) {
    // Two probe grids: one over the object's surface (light rays), one over the ground the
    // shadow rays leave; one grid over both would stretch its few probes over the whole
    // shadow region and blur the volume's light at the object. The shadow grid is 2×2×2: the
    // volume's light enters S of Eq. 4 in numerator and denominator alike, so a coarse grid
    // moves S little (measured: streetlight-bench insert --size kitti, shadow term).
    const RadianceCache fg_cache(in, opt, env_map, rays, 0, fg_rays, opt.cache_max_xz, opt.cache_max_y);
    const RadianceCache sh_cache(in, opt, env_map, rays, fg_rays, rays.size(), opt.cache_shadow_max_xz,
                                 opt.cache_shadow_max_y);
    std::vector<float> l(size_t(3 * rays.size()));
    parallel_for(rays.size(), 256, [&](int64_t b, int64_t e) {
      for (int64_t r = b; r < e; ++r) {
        const RadianceCache& cache = r < fg_rays ? fg_cache : sh_cache;
        const glm::vec3 v = cache.radiance(&rays.origin[size_t(3 * r)], &rays.dir[size_t(3 * r)]);
        for (int c = 0; c < 3; ++c) l[size_t(3 * r + c)] = v[c];
      }
    });
    radiance = as_tensor(l, {rays.size(), 3}, dt);
  } else if (rays.size() > 0) {
    const Tensor o = as_tensor(rays.origin, {rays.size(), 3}, dt), d = as_tensor(rays.dir, {rays.size(), 3}, dt);
    radiance = in.vsg.defined() ? radiance_query(in.vsg, in.env, o, d, in.grid, opt.query).radiance : env_lookup(in.env, d);
  }

  // ---- foreground: C = Σ w·L per pixel (Eq. 2), scattered into the image
  Tensor colour = Tensor::zeros({HW, 3}, dt);
  if (!fg.pixels.empty()) {
    const Tensor per_pixel = weighted_segment_sum(slice(radiance, 0, 0, fg_rays),
                                                  as_tensor(fg.weights, {fg_rays, 3}, dt), fg.offsets);
    std::vector<int64_t> idx;
    for (int64_t p : fg.pixels) idx.insert(idx.end(), {p, p, p});
    colour = scatter_add(colour, 0, Tensor::from_indices(idx, {int64_t(fg.pixels.size()), 3}), per_pixel);
  }

  // ---- shadows: S per computed texel (Eq. 4), 1 elsewhere, upsampled edge-aware
  const int64_t n_texels = int64_t(opt.shadow_width) * opt.shadow_height;
  Tensor s_map = Tensor::ones({n_texels + 1, 3}, dt);  // the extra row is the constant 1
  if (!sh.texels.empty()) {
    // Guard of Eq. 4: S = (Σ L' + ε)/(Σ L + ε), ε = 1e-6 · mean sky radiance (never 0/0).
    const double eps = 1e-6 * std::max(1e-12, mean(in.env.detach().to(DType::F64)).item());
    const Tensor s = shadow_ratio(slice(radiance, 0, fg_rays, fg_rays + sh_rays), sh.weights, sh.visibility, sh.offsets, eps);
    std::vector<int64_t> idx;
    for (int64_t t : sh.texels) idx.insert(idx.end(), {t, t, t});
    s_map = scatter_add(s_map, 0, Tensor::from_indices(idx, {int64_t(sh.texels.size()), 3}), add_scalar(s, -1.0));
  }
  std::vector<int64_t> tap_idx;
  std::vector<double> tap_w;
  upsample_taps(in, opt, sh, depth, tap_idx, tap_w);
  const Tensor taps = index_select(s_map, 0, Tensor::from_indices(tap_idx, {HW * 4}));
  const Tensor tap_weights = Tensor::from_vector(tap_w, {HW * 4, 1}, dt);
  const Tensor s_img = sum(reshape(mul(taps, tap_weights), {HW, 4, 3}), {1});  // [HW, 3]

  // ---- composite: I_edit = α·I_obj + (1 − α)·(S ⊙ I); α·I_obj is `colour` (coverage-weighted)
  const Tensor alpha = as_tensor(fg.coverage, {HW, 1}, dt);
  const Tensor background = reshape(permute(in.background.detach().to(dt), {1, 2, 0}), {HW, 3});
  const Tensor composite = add(colour, mul(rsub_scalar(1.0, alpha), mul(s_img, background)));
  out.composite = reshape(permute(reshape(composite, {H, W, 3}), {2, 0, 1}), {3, H, W});
  out.shadow_map = reshape(permute(reshape(s_img, {H, W, 3}), {2, 0, 1}), {3, H, W});
  out.object_mask = reshape(alpha, {1, H, W});
  out.object_depth = as_tensor(fg.depth, {1, H, W}, dt);
  out.object_silhouette = as_tensor(fg.silhouette, {1, H, W}, dt);
  return out;
}

}  // namespace sl::render