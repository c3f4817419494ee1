// The radiance cache of inference insertion (render/radiance_cache.h): its irradiance against a
// brute-force integral, the fused shading path against rays read through the cache, and the
// diffuse control variate of Eq. 2 (render/object_insertion.h): same mean, less noise.
#include "render/radiance_cache.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

#include "autodiff/gemm_kernel.h"
#include "autodiff/ops.h"
#include "render/environment_map.h"
#include "render/equirect.h"
#include "render/insertion_foreground.h"
#include "render/insertion_ops.h"
#include "render/insertion_shadows.h"
#include "render/object_insertion.h"
#include "render/primitives.h"
#include "util/math.h"

namespace sl::test {
namespace {
using namespace sl::render;

struct Scene {
  InsertionInputs in;
};

// A camera 1.6 m above y = 0 looking at a box 6 m ahead; a sky of 1 with a 400× sun texel and a
// volume of random parameters.
Scene scene(int W = 48, int H = 32) {
  Scene s;
  Camera cam(intrinsics_from_fov(60 * kDegToRad, W, H), rotation_from_yaw_pitch_roll(0, -15 * kDegToRad, 0), {0.0, 1.6, 0.0});
  std::vector<double> d(size_t(W) * H);
  for (int i = 0; i < H; ++i)
    for (int j = 0; j < W; ++j) {
      const CameraRay r = cam.pixel_ray(j, i);
      d[size_t(i) * W + j] = r.direction.y < -1e-6
                                 ? cam.world_to_camera(r.origin + (-r.origin.y / r.direction.y) * r.direction).z
                                 : INFINITY;
    }
  s.in.camera = cam;
  s.in.depth = Tensor::from_vector(d, {H, W}, DType::F32);
  s.in.background = Tensor::full({3, H, W}, 0.3, DType::F32);
  Tensor env = Tensor::ones({3, 16, 32}, DType::F32);
  for (int c = 0; c < 3; ++c) slice(slice(slice(env, 0, c, c + 1), 1, 3, 4), 2, 9, 10).fill_(400.0);
  s.in.env = env;
  s.in.grid.dims = {8, 8, 4};
  s.in.grid.center = {0, 1.6, 0};
  s.in.grid.extent_neg = {20, 2, 20};
  s.in.grid.extent_pos = {20, 8, 20};
  s.in.vsg = vsg_activate(Tensor::uniform({8, 8, 8, 4}, -3, -1, 3), 0).detach().contiguous();
  Material m;
  m.base_color_factor = glm::vec4(0.7f, 0.6f, 0.5f, 1.0f);
  m.roughness = 0.6f;
  m.metallic = 0.0f;
  s.in.objects.push_back(place_object(make_box({-0.6f, 0.0f, -0.6f}, {0.6f, 1.2f, 0.6f}, m), {0.0, -6.0, 20.0, 1.0},
                                      cam, s.in.depth));
  return s;
}

InsertionOptions cached_options() {
  InsertionOptions o;
  o.aa_samples = 2;
  o.light_samples = 16;
  o.shadow_width = 12;
  o.shadow_height = 8;
  o.shadow_rays = 16;
  o.importance_sampling = true;
  o.bilinear_env_sampling = true;
  o.stratify_per_pixel = true;
  o.radiance_cache = true;
  o.cache_height = 16;
  o.cache_width = 32;
  o.query.samples = 16;
  return o;
}

// ∫ max(0, n·l) L(o, l) dΩ and the same with (1 − n·l)^5, by an hq × 2·hq midpoint sum of the
// cache's own radiance().
insertion::RadianceCache::Irradiance brute_irradiance(const insertion::RadianceCache& cache, const glm::vec3& o,
                                                       const glm::vec3& n, int hq) {
  const int wq = 2 * hq;
  glm::dvec3 brute(0.0), brute5(0.0);
  for (int r = 0; r < hq; ++r) {
    const double solid = equirect::pixel_solid_angle(r, wq, hq);
    for (int c = 0; c < wq; ++c) {
      const equirect::Dir d = equirect::uv_to_direction(c + 0.5, r + 0.5, wq, hq);
      const glm::vec3 l(float(d.x), float(d.y), float(d.z));
      const double cosine = glm::dot(n, l);
      if (cosine <= 0) continue;
      const glm::dvec3 L(cache.radiance(&o[0], &l[0]));
      brute += L * cosine * solid;
      brute5 += L * cosine * std::pow(1.0 - cosine, 5) * solid;
    }
  }
  return {glm::vec3(brute), glm::vec3(brute5)};
}

// E(probe, n) against ∫ max(0, n·l) L(probe, l) dΩ (and E₅ with (1 − n·l)^5) by a 512 × 1024 midpoint sum of radiance()
// itself: the two differ by the quadrature of build_irradiance() and the normal-grid reads.
// Measured on this 16 × 32 sky with a one-texel sun: ≤ 1.02% at the default quadrature, ≤ 0.34%
// at 4× (the rest is the pole of the normal grid: ≤ 0.04% elsewhere).
TEST(RadianceCache, IrradianceMatchesABruteForceIntegralOfItsRadiance) {
  const Scene s = scene();
  const InsertionOptions opt = cached_options();
  const EnvironmentMap env_map(s.in.env);
  const glm::vec3 lo(-1.0f, 0.0f, -7.0f), hi(1.0f, 1.5f, -5.0f);
  std::vector<glm::vec3> normals;
  for (const glm::vec3& n : {glm::vec3(0, 1, 0), glm::vec3(1, 0, 0), glm::vec3(0, 0, 1), glm::vec3(-0.6f, 0.3f, 0.74f)})
    normals.push_back(glm::normalize(n));
  for (const auto& [ss, tol] : std::vector<std::pair<int, double>>{{1, 0.015}, {4, 0.004}}) {
    insertion::RadianceCache cache(s.in, opt, env_map, lo, hi, 3, 3);
    ASSERT_GT(cache.probes(), 0);
    cache.build_irradiance(64, ss, normals);
    for (const glm::vec3& o : {lo, hi, 0.5f * (lo + hi)})
      for (const glm::vec3& n : normals) {
        const auto b = brute_irradiance(cache, o, n, 512);
        const glm::dvec3 brute(b.cosine), brute5(b.grazing);
        const auto e = cache.irradiance(o, n);
        for (int ch = 0; ch < 3; ++ch) {
          EXPECT_NEAR(e.cosine[ch], brute[ch], tol * brute[ch]) << "supersample " << ss << ", n " << n.x << "," << n.y << "," << n.z;
          // The grazing term is a small part of E: its error is held to the same share of E.
          EXPECT_NEAR(e.grazing[ch], brute5[ch], tol * brute[ch]) << "supersample " << ss << ", n " << n.x << "," << n.y << "," << n.z;
        }
      }
  }
}

// build_irradiance() leaves out of each block's GEMM the quadrature directions that none of the
// block's normals faces (a zero column adds nothing to any FMA sequence): a normal's E is then
// the same bits among 100 other normals as among 1000 (other blocks, other columns left out).
TEST(RadianceCache, IrradianceOfANormalDoesNotDependOnTheOtherNormals) {
  // A property of the packed GEMM kernel, which computes each element of C alone; a build without
  // it (scalar) keeps Eigen's product, whose blocking follows the product's shape, and every column.
  if (!detail::gemm_kernel_available()) GTEST_SKIP() << "no packed GEMM kernel in this build (scalar path)";
  const Scene s = scene();
  const InsertionOptions opt = cached_options();
  const EnvironmentMap env_map(s.in.env);
  const glm::vec3 lo(-1.0f, 0.0f, -7.0f), hi(1.0f, 1.5f, -5.0f);
  const std::vector<glm::vec3> probe_normals = {glm::vec3(0, 1, 0), glm::normalize(glm::vec3(1, 0.2f, 0)),
                                                glm::normalize(glm::vec3(-0.6f, 0.3f, 0.74f))};
  auto with_random = [&](int count, uint64_t seed) {
    std::vector<glm::vec3> normals = probe_normals;
    const Tensor r = Tensor::uniform({count, 3}, -1, 1, seed);
    for (int64_t i = 0; i < count; ++i) {
      const glm::vec3 n(r.data<float>()[3 * i], r.data<float>()[3 * i + 1], r.data<float>()[3 * i + 2]);
      if (glm::dot(n, n) > 1e-4f) normals.push_back(glm::normalize(n));
    }
    return normals;
  };
  insertion::RadianceCache few(s.in, opt, env_map, lo, hi, 3, 3), many(s.in, opt, env_map, lo, hi, 3, 3);
  few.build_irradiance(64, 1, with_random(100, 7));
  many.build_irradiance(64, 1, with_random(1000, 8));
  for (const glm::vec3& n : probe_normals)
    for (const glm::vec3& o : {lo, hi, 0.5f * (lo + hi)}) {
      const auto a = few.irradiance(o, n), b = many.irradiance(o, n);
      for (int ch = 0; ch < 3; ++ch) {
        EXPECT_GT(a.cosine[ch], 0.0f);
        EXPECT_EQ(a.cosine[ch], b.cosine[ch]) << "n " << n.x << "," << n.y << "," << n.z;
        EXPECT_EQ(a.grazing[ch], b.grazing[ch]) << "n " << n.x << "," << n.y << "," << n.z;
      }
    }
}

// Given the reads' origins, build_irradiance() integrates only the probes each block of normals
// is read with (narrower GEMMs on the packed path): every (origin, normal) pair it was given
// reads the same bits as from the irradiance of every probe.
TEST(RadianceCache, IrradianceForGivenOriginsReadsTheSameBits) {
  const Scene s = scene();
  InsertionOptions opt = cached_options();
  opt.cache_spacing_m = 0.25;  // 6 × 4 × 6 probes: each block of normals reads a part of them
  const EnvironmentMap env_map(s.in.env);
  const glm::vec3 lo(-1.0f, 0.0f, -7.0f), hi(1.0f, 1.5f, -5.0f);
  const Tensor r = Tensor::uniform({1000, 6}, -1, 1, 11);
  std::vector<glm::vec3> normals, origins;
  for (int64_t i = 0; i < 1000; ++i) {
    const float* v = r.data<float>() + 6 * i;
    const glm::vec3 n(v[0], v[1], v[2]);
    if (!(glm::dot(n, n) > 1e-4f)) continue;
    normals.push_back(glm::normalize(n));
    const glm::vec3 t = 0.5f * (glm::vec3(v[3], v[4], v[5]) + 1.0f);  // in [0, 1]³
    origins.push_back(lo + t * (hi - lo));
  }
  insertion::RadianceCache all(s.in, opt, env_map, lo, hi, 6, 4), read(s.in, opt, env_map, lo, hi, 6, 4);
  ASSERT_GT(all.probes(), 8);
  all.build_irradiance(64, 1, normals);
  read.build_irradiance(64, 1, normals, &origins);
  for (size_t i = 0; i < normals.size(); ++i) {
    const auto a = all.irradiance(origins[i], normals[i]), b = read.irradiance(origins[i], normals[i]);
    for (int ch = 0; ch < 3; ++ch) {
      ASSERT_EQ(a.cosine[ch], b.cosine[ch]) << "pair " << i;
      ASSERT_EQ(a.grazing[ch], b.grazing[ch]) << "pair " << i;
    }
  }
}

// A broad sun next to the zenith (rows 0-1 of the sky, as release 0.6.0 estimates for KITTI
// 000008) puts the radiance's steepest change inside the quadrature's polar rows, where the cos(θ)
// weight tilts within a row. Read at each row's solid-angle centroid, the roof's E (n = +y) is
// within 0.1% of the brute-force integral (measured 0.01%; at the rows' middles it was 0.87%,
// which this bound rejects). Vertical faces facing the sun keep about 1.2% here (this 16-row sky
// puts the terminator through an 11° sun; the normal grid's bilinear reads smooth its kink):
// held under 1.5%.
TEST(RadianceCache, IrradianceHoldsUnderASunNextToTheZenith) {
  Scene s = scene();
  Tensor env = Tensor::ones({3, 16, 32}, DType::F32);
  for (int c = 0; c < 3; ++c) {
    slice(slice(slice(env, 0, c, c + 1), 1, 0, 1), 2, 8, 16).fill_(300.0);
    slice(slice(slice(env, 0, c, c + 1), 1, 1, 2), 2, 10, 14).fill_(600.0);
  }
  s.in.env = env;
  InsertionOptions opt = cached_options();
  const EnvironmentMap env_map(s.in.env);
  const glm::vec3 lo(-1.0f, 0.0f, -7.0f), hi(1.0f, 1.5f, -5.0f);
  std::vector<glm::vec3> normals;
  for (const glm::vec3& n : {glm::vec3(0, 1, 0), glm::vec3(1, 0, 0), glm::vec3(0, 0, 1), glm::vec3(-1, 0, 0),
                             glm::vec3(0, 0, -1), glm::vec3(0.6f, 0, 0.8f)})
    normals.push_back(glm::normalize(n));
  insertion::RadianceCache cache(s.in, opt, env_map, lo, hi, 3, 3);
  cache.build_irradiance(128, 1, normals);
  const glm::vec3 o = 0.5f * (lo + hi);
  for (const glm::vec3& n : normals) {
    const glm::dvec3 brute(brute_irradiance(cache, o, n, 1024).cosine);
    const auto e = cache.irradiance(o, n);
    for (int ch = 0; ch < 3; ++ch)
      EXPECT_NEAR(e.cosine[ch], brute[ch], (n.y > 0.99f ? 0.001 : 0.015) * brute[ch]) << "n " << n.x << "," << n.y << "," << n.z;
  }
}

// shade_foreground() reads each light ray from the cache as it is drawn; trace_foreground()
// stores the rays and weights. Summing w·L per pixel of the stored rays gives the same image.
TEST(RadianceCache, FusedShadingEqualsStoredRaysReadThroughTheCache) {
  const Scene s = scene();
  for (bool cv : {false, true}) {
    InsertionOptions opt = cached_options();
    opt.diffuse_control_variate = cv;
    const EnvironmentMap env_map(s.in.env);
    const Tensor depth_t = s.in.depth.to(DType::F64).contiguous();
    insertion::Foreground fg, fg2;
    InsertionStats stats;
    const auto gs = insertion::gbuffer(s.in, opt, s.in.objects[0].mesh, *s.in.objects[0].bvh, depth_t.data<double>(), fg, stats);
    ASSERT_GT(gs.size(), 10u);
    fg.light_samples = fg2.light_samples = opt.light_samples;
    std::vector<glm::vec3> origins, normals;
    for (const auto& g : gs) {
      origins.push_back(insertion::light_origin(g));
      normals.push_back(g.n);
    }
    glm::vec3 lo, hi;
    insertion::origin_bounds(origins, lo, hi);
    insertion::RadianceCache cache(s.in, opt, env_map, lo, hi, opt.cache_max_xz, opt.cache_max_y);
    if (cv) cache.build_irradiance(opt.cv_normals_height, opt.cv_quadrature_supersample, normals);
    std::vector<float> fused;
    insertion::shade_foreground(opt, *s.in.objects[0].bvh, env_map, gs, cache, cv, fg, fused);

    insertion::QueryRays rays;
    rays.resize(int64_t(gs.size()) * opt.light_samples);
    insertion::trace_foreground(opt, *s.in.objects[0].bvh, env_map, gs, fg2, rays, cv);
    ASSERT_EQ(fg.pixels, fg2.pixels);
    const int N = opt.light_samples;
    double err = 0, ref = 0;
    for (size_t p = 0; p < fg2.pixels.size(); ++p) {
      glm::dvec3 acc(0.0);
      for (int64_t r = fg2.offsets[p]; r < fg2.offsets[p + 1]; ++r) {
        const glm::vec3 L = cache.radiance(&rays.origin[size_t(3 * r)], &rays.dir[size_t(3 * r)]);
        for (int c = 0; c < 3; ++c) acc[c] += double(fg2.weights[size_t(3 * r + c)]) * L[c];
        if (cv && (r - fg2.offsets[p]) % N == 0) {
          const auto& g = gs[size_t(r / N)];
          const disney::DiffuseControl d = disney::diffuse_control(g.material, glm::dot(g.n, g.wo));
          const auto e = cache.irradiance(insertion::light_origin(g), g.n);
          acc += glm::dvec3(d.c * (e.cosine + d.kappa * e.grazing)) / double(opt.aa_samples);
        }
      }
      for (int c = 0; c < 3; ++c) {
        acc[c] = std::max(0.0, acc[c]);  // shade_foreground's clamp
        err += (acc[c] - fused[3 * p + size_t(c)]) * (acc[c] - fused[3 * p + size_t(c)]);
        ref += acc[c] * acc[c];
      }
    }
    EXPECT_LT(std::sqrt(err / ref), 1e-4) << "control variate " << cv;
  }
}

// shade_shadows() and upsample_shadows() against the stored rays read through the cache, the
// tape's shadow_ratio and the upsampling taps.
TEST(RadianceCache, FusedShadowsEqualStoredRaysShadowRatioAndTaps) {
  const Scene s = scene();
  const InsertionOptions opt = cached_options();
  const EnvironmentMap env_map(s.in.env);
  const Tensor depth_t = s.in.depth.to(DType::F64).contiguous();
  const double* depth = depth_t.data<double>();
  const Bvh& bvh = *s.in.objects[0].bvh;
  insertion::Shadows fused, stored;
  InsertionStats st1, st2;
  const auto origins = insertion::shadow_texels(s.in, opt, bvh.bounds(), env_map, depth, fused, st1);
  ASSERT_GT(fused.texels.size(), 4u);
  std::vector<glm::vec3> used;
  for (int64_t t : fused.texels) used.push_back(origins[size_t(t)]);
  glm::vec3 lo, hi;
  insertion::origin_bounds(used, lo, hi);
  const insertion::RadianceCache cache(s.in, opt, env_map, lo, hi, opt.cache_shadow_max_xz, opt.cache_shadow_max_y);
  const double eps = 1e-6;
  std::vector<float> ratio;
  insertion::shade_shadows(opt, bvh, env_map, fused, origins, cache, eps, ratio);

  insertion::QueryRays rays;
  insertion::trace_shadows(s.in, opt, bvh.bounds(), bvh, env_map, depth, stored, rays, st2);
  ASSERT_EQ(stored.texels, fused.texels);
  std::vector<float> l(size_t(3 * rays.size()));
  for (int64_t r = 0; r < rays.size(); ++r) {
    const glm::vec3 v = cache.radiance(&rays.origin[size_t(3 * r)], &rays.dir[size_t(3 * r)]);
    for (int c = 0; c < 3; ++c) l[size_t(3 * r + c)] = v[c];
  }
  const Tensor L = Tensor::from_vector(std::vector<double>(l.begin(), l.end()), {rays.size(), 3}, DType::F64);
  const auto S = shadow_ratio(L, stored.weights, stored.visibility, stored.offsets, eps).to_vector();
  ASSERT_EQ(S.size(), ratio.size());
  bool shadowed = false;
  for (size_t i = 0; i < S.size(); ++i) {
    EXPECT_NEAR(ratio[i], S[i], 2e-5 * std::max(1.0, S[i])) << i;
    shadowed = shadowed || S[i] < 0.9;
  }
  EXPECT_TRUE(shadowed);

  // Upsampling: the taps' weighted sum over S (1 on uncomputed texels) at every pixel.
  std::vector<float> s_img;
  insertion::upsample_shadows(s.in, opt, fused, depth, ratio, s_img);
  std::vector<int64_t> idx;
  std::vector<double> w;
  insertion::upsample_taps(s.in, opt, fused, depth, idx, w);
  std::vector<double> texel(size_t(3 * (opt.shadow_width * opt.shadow_height + 1)), 1.0);
  for (size_t i = 0; i < fused.texels.size(); ++i)
    for (int c = 0; c < 3; ++c) texel[size_t(3 * fused.texels[i] + c)] = ratio[3 * i + size_t(c)];
  const size_t HW = s_img.size() / 3;
  for (size_t p = 0; p < HW; ++p)
    for (int c = 0; c < 3; ++c) {
      double v = 0;
      for (int k = 0; k < 4; ++k) v += w[4 * p + size_t(k)] * texel[size_t(3 * idx[4 * p + size_t(k)] + c)];
      ASSERT_NEAR(s_img[3 * p + size_t(c)], v, 1e-6) << "pixel " << p;
    }
}

// Exact directions: a ray toward sky brighter than the threshold (the scene's 400× sun texel)
// reads the exact march from its own origin; every other ray reads the probes unchanged.
TEST(RadianceCache, ExactDirectionsReadTheMarchAndTheRestReadTheProbes) {
  const Scene s = scene();
  const InsertionOptions opt = cached_options();
  const EnvironmentMap env_map(s.in.env);
  const glm::vec3 lo(-3.0f, 0.0f, -9.0f), hi(3.0f, 0.2f, -3.0f);
  const insertion::RadianceCache plain(s.in, opt, env_map, lo, hi, 2, 2);
  const insertion::RadianceCache exact(s.in, opt, env_map, lo, hi, 2, 2, 10.0);
  const RayMarcher march(s.in.vsg, s.in.env, s.in.grid, opt.query);
  // The sun texel (row 3, column 9 of 16×32) and a direction of sky 1.
  const equirect::Dir sd = equirect::uv_to_direction(9.5, 3.5, 32, 16);
  const glm::vec3 sun(float(sd.x), float(sd.y), float(sd.z)), sky = glm::normalize(glm::vec3(0.3f, 0.5f, 0.8f));
  int differ = 0;
  for (const glm::vec3& o : {lo, hi, glm::vec3(0.7f, 0.1f, -4.3f), glm::vec3(-2.2f, 0.05f, -8.1f)}) {
    const glm::vec3 a = exact.radiance(&o[0], &sun[0]);
    // radiance() marches the direction rebuilt from its panorama coordinates (float rounding).
    const glm::vec3 m = march(&o[0], &sun[0]).radiance;
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(a[c], m[c], 1e-5 * m[c]);
    differ += glm::length(a - plain.radiance(&o[0], &sun[0])) > 1e-4f * glm::length(m) ? 1 : 0;
    const glm::vec3 b = exact.radiance(&o[0], &sky[0]), p = plain.radiance(&o[0], &sky[0]);
    for (int c = 0; c < 3; ++c) EXPECT_EQ(b[c], p[c]);
  }
  EXPECT_GT(differ, 0);  // the probes' sun is not the march's everywhere
  EXPECT_EQ(exact.exact_rays(), 4);
}

// Lean: a threshold above the brightest sky marches nothing and gives the same bits as none.
// With every direction exact, the shadows no longer depend on the probe grid.
TEST(RadianceCache, ExactShadowDirectionsAboveTheSkyChangeNothingAndAllExactIgnoresTheProbes) {
  const Scene s = scene();
  InsertionOptions none = cached_options(), above = none;
  none.cache_shadow_exact_sky = 0;
  above.cache_shadow_exact_sky = 1e9;
  const InsertionResult a = insert_objects(s.in, none), b = insert_objects(s.in, above);
  EXPECT_EQ(b.stats.exact_query_rays, 0);
  EXPECT_EQ(a.composite.to_vector(), b.composite.to_vector());
  EXPECT_EQ(a.shadow_map.to_vector(), b.shadow_map.to_vector());

  InsertionOptions all = none;
  all.cache_shadow_exact_sky = 1e-3;  // every texel of the scene's sky is ≥ 1 ≥ 1e-3 × its mean
  InsertionOptions all_fine = all;
  all_fine.cache_shadow_max_xz = 6;
  all_fine.cache_shadow_height = 4;
  const InsertionResult c = insert_objects(s.in, all), d = insert_objects(s.in, all_fine);
  EXPECT_GT(c.stats.exact_query_rays, 0);
  EXPECT_EQ(c.stats.exact_query_rays, d.stats.exact_query_rays);
  EXPECT_EQ(c.shadow_map.to_vector(), d.shadow_map.to_vector());
  EXPECT_NE(a.shadow_map.to_vector(), c.shadow_map.to_vector());
}

// Lean: a sparse grid (only the cells that hold an origin) reads the dense grid's values at
// those origins bit for bit, and builds fewer probes; insertion gives the same image (the
// control variate's irradiance is a GEMM over fewer probes: equal to float rounding).
TEST(RadianceCache, SparseProbesReadTheDenseValuesWhereTheRaysStart) {
  const Scene s = scene();
  const InsertionOptions opt = cached_options();
  const EnvironmentMap env_map(s.in.env);
  // Origins on two faces of a box: the grid's inner cells hold none.
  std::vector<glm::vec3> origins;
  for (int i = 0; i <= 10; ++i)
    for (int j = 0; j <= 10; ++j) {
      origins.emplace_back(-2.0f + 0.4f * float(i), 0.1f + 0.2f * float(j), -8.0f);
      origins.emplace_back(2.0f, 0.1f + 0.2f * float(j), -8.0f + 0.4f * float(i));
    }
  glm::vec3 lo, hi;
  insertion::origin_bounds(origins, lo, hi);
  InsertionOptions fine = opt;
  fine.cache_spacing_m = 0.5;
  const insertion::RadianceCache dense(s.in, fine, env_map, lo, hi, 9, 5);
  const insertion::RadianceCache sparse(s.in, fine, env_map, lo, hi, 9, 5, 0.0, &origins);
  EXPECT_LT(sparse.probes(), dense.probes());
  const std::vector<glm::vec3> dirs = {glm::normalize(glm::vec3(0.3f, 0.5f, 0.8f)), glm::vec3(0, 1, 0),
                                       glm::normalize(glm::vec3(-0.7f, -0.2f, 0.1f))};
  for (const glm::vec3& o : origins)
    for (const glm::vec3& d : dirs) {
      const glm::vec3 a = dense.radiance(&o[0], &d[0]), b = sparse.radiance(&o[0], &d[0]);
      for (int c = 0; c < 3; ++c) ASSERT_EQ(a[c], b[c]);
    }
  for (bool cv : {false, true}) {
    InsertionOptions on = opt, off = opt;
    on.diffuse_control_variate = off.diffuse_control_variate = cv;
    on.cache_sparse = true;
    off.cache_sparse = false;
    on.cache_spacing_m = off.cache_spacing_m = 0.3;  // fine enough that the object's box has empty cells
    on.cache_max_xz = off.cache_max_xz = 8;
    const auto a = insert_objects(s.in, on).composite.to_vector(), b = insert_objects(s.in, off).composite.to_vector();
    ASSERT_EQ(a.size(), b.size());
    for (size_t i = 0; i < a.size(); ++i) {
      if (cv)
        ASSERT_NEAR(a[i], b[i], 1e-5 * std::max(1.0, std::abs(b[i]))) << i;
      else
        ASSERT_EQ(a[i], b[i]) << i;
    }
  }
}

// Relative RMSE over the object's fully covered pixels.
double object_error(const InsertionResult& a, const InsertionResult& b) {
  const auto va = a.composite.to_vector(), vb = b.composite.to_vector(), m = b.object_mask.to_vector();
  const size_t hw = m.size();
  double e = 0, r = 0;
  for (size_t p = 0; p < hw; ++p)
    if (m[p] >= 1)
      for (size_t c = 0; c < 3; ++c) {
        e += (va[c * hw + p] - vb[c * hw + p]) * (va[c * hw + p] - vb[c * hw + p]);
        r += vb[c * hw + p] * vb[c * hw + p];
      }
  return std::sqrt(e / r);
}

// The control variate changes the estimator, not its mean: over 8 seeds its average agrees
// with the plain estimator's 8-seed average to within their noise, and one run's noise (the
// spread between two seeds) is less than half the plain estimator's.
// The mean composite of n runs with lighting seeds first, first + 1, …
InsertionResult mean_of(const Scene& s, InsertionOptions o, int n, uint64_t first) {
  Tensor sum;
  InsertionResult last;
  for (int k = 0; k < n; ++k) {
    o.lighting_seed = first + uint64_t(k);
    last = insert_objects(s.in, o);
    sum = k == 0 ? last.composite : add(sum, last.composite);
  }
  last.composite = mul_scalar(sum, 1.0 / n);
  return last;
}

// One run's noise over the object: the error between two lighting seeds, / √2.
double noise_of(const Scene& s, InsertionOptions o) {
  o.lighting_seed = 1;
  const InsertionResult a = insert_objects(s.in, o);
  o.lighting_seed = 2;
  return object_error(a, insert_objects(s.in, o)) / std::sqrt(2.0);
}

// Expects a and b to have the same mean: their 8-seed means differ by less than 3σ of that
// difference, √((n_a² + n_b²)/8), plus 0.003. Returns the two estimators' noises.
std::pair<double, double> expect_same_mean(const Scene& s, const InsertionOptions& a, const InsertionOptions& b,
                                           uint64_t first_seed) {
  const double n_a = noise_of(s, a), n_b = noise_of(s, b);
  const double diff = object_error(mean_of(s, a, 8, first_seed), mean_of(s, b, 8, first_seed));
  EXPECT_LT(diff, 3.0 * std::sqrt((n_a * n_a + n_b * n_b) / 8.0) + 0.003) << "noises " << n_a << ", " << n_b;
  return {n_a, n_b};
}

TEST(RadianceCache, ControlVariateKeepsTheMeanAndCutsTheNoise) {
  const Scene s = scene();
  InsertionOptions plain = cached_options();
  InsertionOptions cv = plain;
  cv.diffuse_control_variate = true;
  const auto [n_cv, n_plain] = expect_same_mean(s, cv, plain, 100);
  EXPECT_GT(n_plain, 0.0);
  EXPECT_LT(n_cv, 0.5 * n_plain) << "plain " << n_plain << " cv " << n_cv;
}

// Adaptive sampling (render/object_insertion.h): N = 8 plus on average 8 more where the
// neighbours were noisy keeps the mean of N = 16 everywhere (its extra samples never depend on
// a pixel's own first pass), at the same number of light rays.
TEST(AdaptiveSampling, KeepsTheMeanAtTheSameNumberOfRays) {
  const Scene s = scene(64, 48);
  InsertionOptions uniform = cached_options();
  uniform.diffuse_control_variate = true;
  InsertionOptions adaptive = uniform;
  adaptive.light_samples = 8;
  adaptive.adaptive_light_samples = 8;
  const InsertionResult one = insert_objects(s.in, adaptive);
  const int64_t samples = one.stats.foreground_samples;
  ASSERT_GT(samples, 100);
  // The extra rays average 8 per visible primary sample (each pixel rounds to even).
  EXPECT_NEAR(double(one.stats.adaptive_light_rays), 8.0 * double(samples), 1.0 * double(samples));
  EXPECT_GT(one.stats.adaptive_light_rays, 0);
  const auto [n_adaptive, n_uniform] = expect_same_mean(s, adaptive, uniform, 300);
  EXPECT_GT(n_adaptive, 0.0);
  EXPECT_GT(n_uniform, 0.0);
}

// The residual filter (render/object_insertion.h, "Denoising"): much less noise from seed to
// seed, a mean that moves by less than one unfiltered run's noise (its bias, on this box under a
// volume of random parameters: a stress case whose light changes from pixel to pixel), and the
// coverage, shadows and everything outside the object untouched.
TEST(ResidualFilter, CutsTheNoiseWithASmallBiasAndTouchesNothingElse) {
  const Scene s = scene(96, 64);
  InsertionOptions plain = cached_options();
  plain.diffuse_control_variate = true;
  InsertionOptions filtered = plain;
  filtered.denoise_radius = 2;
  const double n_plain = noise_of(s, plain), n_filtered = noise_of(s, filtered);
  const double bias = object_error(mean_of(s, filtered, 16, 500), mean_of(s, plain, 16, 500));
  std::printf("noise plain %.4f filtered %.4f; mean difference %.4f\n", n_plain, n_filtered, bias);
  EXPECT_LT(n_filtered, 0.5 * n_plain);
  EXPECT_LT(bias, n_plain);
  plain.lighting_seed = filtered.lighting_seed = 9;
  const InsertionResult a = insert_objects(s.in, plain), b = insert_objects(s.in, filtered);
  EXPECT_EQ(a.object_mask.to_vector(), b.object_mask.to_vector());
  EXPECT_EQ(a.shadow_map.to_vector(), b.shadow_map.to_vector());
  const auto ca = a.composite.to_vector(), cb = b.composite.to_vector(), m = a.object_mask.to_vector();
  for (size_t p = 0; p < m.size(); ++p) {
    if (m[p] != 0) continue;
    for (size_t c = 0; c < 3; ++c) EXPECT_EQ(ca[c * m.size() + p], cb[c * m.size() + p]);
  }
}

// Exact corrections (render/object_insertion.h): with every ray corrected (M = N) and no
// filter, the cached sums plus their corrections are the exact sums. So the object is the one
// exact queries give, and the shadows the ones of a cache whose every shadow ray is marched
// exactly (the same directions; exact queries draw other shadow directions), to float rounding.
// With M = 0 nothing changes, bit for bit.
TEST(ExactCorrection, EveryRayCorrectedGivesTheExactSums) {
  const Scene s = scene();
  InsertionOptions cached = cached_options();
  cached.cache_height = 4;  // a coarse cache, so its bias is large
  cached.cache_width = 8;
  InsertionOptions exact = cached;
  exact.radiance_cache = false;
  InsertionOptions exact_shadows = cached;
  exact_shadows.cache_shadow_exact_sky = 1e-3;  // every texel of the sky is ≥ 1e-3 × its mean
  InsertionOptions corrected = cached;
  corrected.cache_exact_light_rays = cached.light_samples;
  corrected.cache_shadow_exact_rays = cached.shadow_rays;
  corrected.cache_exact_filter_radius = 0;
  corrected.cache_shadow_exact_filter_radius = 0;
  const InsertionResult a = insert_objects(s.in, cached), b = insert_objects(s.in, exact),
                        c = insert_objects(s.in, corrected), e = insert_objects(s.in, exact_shadows);
  EXPECT_EQ(a.stats.exact_correction_rays, 0);
  EXPECT_GT(c.stats.exact_correction_rays, c.stats.foreground_samples);
  const auto va = a.composite.to_vector(), vb = b.composite.to_vector(), vc = c.composite.to_vector();
  const auto mask = b.object_mask.to_vector();
  double worst_cached = 0, worst_corrected = 0;
  int object_values = 0;
  for (size_t i = 0; i < vb.size(); ++i) {
    if (mask[i % mask.size()] < 1) continue;  // edges also show the shadows, drawn differently
    ++object_values;
    const double scale = std::max(1.0, std::abs(double(vb[i])));
    worst_cached = std::max(worst_cached, std::abs(double(va[i]) - vb[i]) / scale);
    worst_corrected = std::max(worst_corrected, std::abs(double(vc[i]) - vb[i]) / scale);
  }
  ASSERT_GT(object_values, 30);
  // 2 × 16 light rays of weights up to the sun's, summed in float in two orders: ~1e-6 relative.
  EXPECT_LT(worst_corrected, 1e-4) << "cached " << worst_cached;
  EXPECT_GT(worst_cached, 100 * worst_corrected);
  const auto sa = a.shadow_map.to_vector(), sc = c.shadow_map.to_vector(), se = e.shadow_map.to_vector();
  double shadow_cached = 0;
  for (size_t i = 0; i < se.size(); ++i) {
    ASSERT_NEAR(sc[i], se[i], 1e-5) << i;
    shadow_cached = std::max(shadow_cached, std::abs(double(sa[i]) - se[i]));
  }
  EXPECT_GT(shadow_cached, 1e-3);

  InsertionOptions zero = cached;
  zero.cache_exact_filter_radius = 3;  // radii without rays change nothing
  zero.cache_shadow_exact_filter_radius = 1;
  const InsertionResult d = insert_objects(s.in, zero);
  EXPECT_EQ(a.composite.to_vector(), d.composite.to_vector());
  EXPECT_EQ(a.shadow_map.to_vector(), d.shadow_map.to_vector());
}

// With a few corrected rays per sample the correction is an estimate: over 16 seeds the
// corrected cache's mean agrees with exact queries' mean within their noise, where the
// uncorrected cache's mean is off by more than that.
TEST(ExactCorrection, AFewRaysRemoveTheCachesBiasOnAverage) {
  const Scene s = scene();
  InsertionOptions cached = cached_options();
  cached.cache_height = 4;
  cached.cache_width = 8;
  InsertionOptions exact = cached;
  exact.radiance_cache = false;
  InsertionOptions corrected = cached;
  corrected.cache_exact_light_rays = 8;
  corrected.cache_exact_filter_radius = 0;
  const double n_exact = noise_of(s, exact), n_corrected = noise_of(s, corrected);
  const InsertionResult mean_exact = mean_of(s, exact, 16, 700);
  const double bias_cached = object_error(mean_of(s, cached, 16, 700), mean_exact);
  const double bias_corrected = object_error(mean_of(s, corrected, 16, 700), mean_exact);
  const double bound = 3.0 * std::sqrt((n_exact * n_exact + n_corrected * n_corrected) / 16.0);
  std::printf("noise exact %.4f corrected %.4f; mean error cached %.4f corrected %.4f (bound %.4f)\n", n_exact,
              n_corrected, bias_cached, bias_corrected, bound);
  EXPECT_LT(bias_corrected, bound);
  EXPECT_GT(bias_cached, bound);
}

}  // namespace
}  // namespace sl::test
