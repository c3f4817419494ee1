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
#include "render/radiance_cache.h"
#include "render/sampling.h"
#include "util/math.h"
#include "util/parallel.h"
#include "util/random.h"

namespace sl::render {
namespace {

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
  SL_CHECK(std::isfinite(opt.cache_shadow_exact_sky) && opt.cache_shadow_exact_sky >= 0,
           "insert_objects: cache_shadow_exact_sky ", opt.cache_shadow_exact_sky, " must be finite and >= 0");
  SL_CHECK(opt.cache_exact_light_rays >= 0 && opt.cache_shadow_exact_rays >= 0 && opt.cache_exact_light_rays <= 64 &&
               opt.cache_shadow_exact_rays <= 64 && opt.cache_exact_filter_radius >= 0 &&
               opt.cache_exact_filter_radius <= 16 && opt.cache_shadow_exact_filter_radius >= 0 &&
               opt.cache_shadow_exact_filter_radius <= 16,
           "insert_objects: exact correction rays (light ", opt.cache_exact_light_rays, ", shadow ",
           opt.cache_shadow_exact_rays, ": 0..64) and filter radii (", opt.cache_exact_filter_radius, ", ",
           opt.cache_shadow_exact_filter_radius, ": 0..16) are invalid");
  SL_CHECK(std::isfinite(opt.adaptive_light_samples) && opt.adaptive_light_samples >= 0 && opt.adaptive_max_factor >= 0,
           "insert_objects: adaptive_light_samples ", opt.adaptive_light_samples, " and adaptive_max_factor ",
           opt.adaptive_max_factor, " must be >= 0");
  SL_CHECK(opt.denoise_radius >= 0 && opt.denoise_radius <= 16 && opt.denoise_normal_sigma > 0 &&
               opt.denoise_depth_sigma > 0 && opt.denoise_variance_sigma >= 0,
           "insert_objects: denoise radius ", opt.denoise_radius, " (0..16) and sigmas (normal ",
           opt.denoise_normal_sigma, ", depth ", opt.denoise_depth_sigma, " > 0; variance ",
           opt.denoise_variance_sigma, " >= 0) are invalid");
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
  // Inference with the radiance cache (render/radiance_cache.h): light rays are read from the
  // object's probes as they are drawn, never stored. Two probe grids: one over the object's
  // surface (light rays), one over the ground the shadow rays leave; one grid over both would
  // stretch its few probes over the whole shadow region and blur the volume's light at the
  // object. The shadow grid is coarser (cache_shadow_max_*): the volume's light enters S of
  // Eq. 4 in numerator and denominator alike (measured: streetlight-bench insert, shadow term).
  const bool cached = opt.radiance_cache && in.vsg.defined();
  // Guard of Eq. 4: S = (Σ L' + ε)/(Σ L + ε), ε = 1e-6 · mean sky radiance (never 0/0).
  const double sky_mean = mean(in.env.detach().to(DType::F64)).item();
  const double eps = 1e-6 * std::max(1e-12, sky_mean);
  if (cached) {
    // Inference with the radiance cache: every light and shadow ray is read from the probes as
    // it is drawn, and the image is assembled by plain loops (no ray buffer, no tape).
    const bool cv = opt.diffuse_control_variate;
    std::vector<float> shaded, ratio;  // Σ w·L (+ c·E/aa) per pixel of fg.pixels; S per texel of sh.texels
    if (!bvh.empty()) {
      // One float32 copy of the volume marches everything: both caches' probes, the shadow
      // cache's exact directions and the exact corrections (a copy each was three, 2 MB apiece).
      const RayMarcher volume(in.vsg, in.env, in.grid, opt.query);
      if (!gs.empty()) {
        std::vector<glm::vec3> origins(gs.size()), normals(gs.size());
        for (size_t i = 0; i < gs.size(); ++i) {
          origins[i] = light_origin(gs[i]);
          normals[i] = gs[i].n;
        }
        glm::vec3 lo, hi;
        origin_bounds(origins, lo, hi);
        RadianceCache fg_cache(in, opt, env_map, lo, hi, opt.cache_max_xz, opt.cache_max_y, 0.0,
                               opt.cache_sparse ? &origins : nullptr, &volume);
        if (cv) fg_cache.build_irradiance(opt.cv_normals_height, opt.cv_quadrature_supersample, normals, &origins);
        shade_foreground(opt, bvh, env_map, gs, fg_cache, cv, fg, shaded,
                         opt.cache_exact_light_rays > 0 ? &volume : nullptr);
        out.stats.exact_correction_rays += fg.exact_correction_rays;
      }
      const std::vector<glm::vec3> texel_origins = shadow_texels(in, opt, bvh.bounds(), env_map, depth, sh, out.stats);
      if (!sh.texels.empty()) {
        std::vector<glm::vec3> origins;
        for (int64_t t : sh.texels) origins.push_back(texel_origins[size_t(t)]);
        glm::vec3 lo, hi;
        origin_bounds(origins, lo, hi);
        InsertionOptions sh_opt = opt;
        if (opt.cache_shadow_height > 0) {
          sh_opt.cache_height = std::max(2, opt.cache_shadow_height);
          sh_opt.cache_width = 2 * sh_opt.cache_height;
        }
        const RadianceCache sh_cache(in, sh_opt, env_map, lo, hi, opt.cache_shadow_max_xz, opt.cache_shadow_max_y,
                                     opt.cache_shadow_exact_sky * sky_mean, opt.cache_sparse ? &origins : nullptr,
                                     &volume);
        out.stats.exact_correction_rays += shade_shadows(opt, bvh, env_map, sh, texel_origins, sh_cache, eps, ratio,
                                                         opt.cache_shadow_exact_rays > 0 ? &volume : nullptr);
        out.stats.exact_query_rays = sh_cache.exact_rays();
      }
    } else {
      sh.texel_depth.assign(size_t(opt.shadow_width) * opt.shadow_height, 0.0f);
      out.stats.shadow_pixels_total = int64_t(opt.shadow_width) * opt.shadow_height;
    }
    out.stats.adaptive_light_rays = fg.extra_light_rays;
    out.stats.query_rays = int64_t(gs.size()) * fg.light_samples + fg.extra_light_rays +
                           int64_t(sh.texels.size()) * opt.shadow_rays;
    std::vector<float> s_img;
    upsample_shadows(in, opt, sh, depth, ratio, s_img);
    // I_edit = α·I_obj + (1 − α)·(S ⊙ I), written channel-first. α·I_obj is `shaded` at the
    // object's pixels (fg.pixels, increasing) and 0 elsewhere, read in step with p (no image of it).
    SL_CHECK(std::is_sorted(fg.pixels.begin(), fg.pixels.end()) &&
                 std::adjacent_find(fg.pixels.begin(), fg.pixels.end()) == fg.pixels.end(),
             "insert_objects: the object's pixels are not increasing");
    const Tensor bg = in.background.detach().to(DType::F32).contiguous();
    const float* pb = bg.data<float>();
    Tensor comp = Tensor::empty({3, H, W}, DType::F32), smap = Tensor::empty({3, H, W}, DType::F32);
    float *pc = comp.data<float>(), *ps = smap.data<float>();
    parallel_for(HW, 4096, [&](int64_t b, int64_t e) {
      size_t i = size_t(std::lower_bound(fg.pixels.begin(), fg.pixels.end(), b) - fg.pixels.begin());
      for (int64_t p = b; p < e; ++p) {
        const bool object = i < fg.pixels.size() && fg.pixels[i] == p;
        for (int c = 0; c < 3; ++c) {
          const float S = s_img[size_t(3 * p + c)];
          const float colour = object ? shaded[3 * i + size_t(c)] : 0.0f;
          ps[c * HW + p] = S;
          pc[c * HW + p] = colour + (1.0f - fg.coverage[size_t(p)]) * S * pb[c * HW + p];
        }
        if (object) ++i;
      }
    });
    out.composite = comp.to(dt);
    out.shadow_map = smap.to(dt);
    out.object_mask = as_tensor(fg.coverage, {1, H, W}, dt);
    out.object_depth = as_tensor(fg.depth, {1, H, W}, dt);
    out.object_silhouette = as_tensor(fg.silhouette, {1, H, W}, dt);
    return out;
  }

  // Exact queries (training and refinement: on the tape).
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
  if (rays.size() > 0) {
    const Tensor o = as_tensor(rays.origin, {rays.size(), 3}, dt), d = as_tensor(rays.dir, {rays.size(), 3}, dt);
    radiance = in.vsg.defined() ? radiance_query(in.vsg, in.env, o, d, in.grid, opt.query).radiance : env_lookup(in.env, d);
  }

  // ---- foreground: C = Σ w·L per pixel (Eq. 2), scattered into the image
  Tensor colour = Tensor::zeros({HW, 3}, dt);
  if (!fg.pixels.empty()) {
    const Tensor per_pixel =
        weighted_segment_sum(slice(radiance, 0, 0, fg_rays), as_tensor(fg.weights, {fg_rays, 3}, dt), fg.offsets);
    std::vector<int64_t> idx;
    for (int64_t p : fg.pixels) idx.insert(idx.end(), {p, p, p});
    colour = scatter_add(colour, 0, Tensor::from_indices(idx, {int64_t(fg.pixels.size()), 3}), per_pixel);
  }

  // ---- shadows: S per computed texel (Eq. 4), 1 elsewhere, upsampled edge-aware
  const int64_t n_texels = int64_t(opt.shadow_width) * opt.shadow_height;
  Tensor s_map = Tensor::ones({n_texels + 1, 3}, dt);  // the extra row is the constant 1
  if (!sh.texels.empty()) {
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