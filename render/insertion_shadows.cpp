// Eq. 3-4: the shadow rays and the edge-aware upsampling of the ratio shadow map (see
// insertion_shadows.h).
#include "render/insertion_shadows.h"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <tuple>

#include "render/equirect.h"
#include "render/exact_correction.h"
#include "render/sampling.h"
#include "util/math.h"
#include "util/parallel.h"
#include "util/random.h"

namespace sl::render::insertion {
namespace {

// The k-th shadow direction of texel t and its weight cos/pdf (0 marks an unusable sample).
// The weight cos θ / pdf of a shadow ray under the mixture of the cosine lobe (share c_cos) and
// the sky's density env_pdf; 0 below the horizon or where the mixture has no density.
inline double mixture_weight(double cos_t, double c_cos, double env_pdf) {
  const double pdf = c_cos * std::max(0.0, cos_t) / kPi + (1.0 - c_cos) * env_pdf;
  return (cos_t > 0 && pdf > 0) ? cos_t / pdf : 0.0;
}

struct ShadowSampler {
  const InsertionOptions& opt;
  const EnvironmentMap& env_map;
  uint64_t seed, choice_seed, rot_seed;
  Frame frame{glm::vec3(0, 1, 0)};
  // The split sampling's rotations of texel t (split_sample(rot_seed, t, …) draws them per ray):
  // once per texel for the loops over its rays.
  SplitRotations rotations(int64_t t) const { return split_rotations(rot_seed, uint64_t(t)); }
  // The direction alone (what the texel pruning needs: no density). Every draw takes its texel's
  // rotations, made once by the caller's loop over the texel's rays.
  glm::vec3 direction(int64_t t, int k, const SplitRotations& rot) const {
    if (!opt.importance_sampling) {
      const float u1 = uniform01f(seed, uint64_t(t), 2 * k), u2 = uniform01f(seed, uint64_t(t), 2 * k + 1);
      return frame.to_world(cosine_hemisphere(u1, u2));
    }
    // Inference: cosine + environment samples, so a hard sun is found; split and stratified
    // (a single ray: one-sample mixture).
    const int N = opt.shadow_rays, n_cos = N / 2;
    if (n_cos == 0) {
      const float u1 = uniform01f(seed, uint64_t(t), 2 * k), u2 = uniform01f(seed, uint64_t(t), 2 * k + 1);
      return uniform01f(choice_seed, uint64_t(t), k) < 0.5f ? frame.to_world(cosine_hemisphere(u1, u2))
                                                           : env_sample(env_map, opt, u1, u2);
    }
    const SplitSample sp = split_sample(rot, k, N, n_cos);
    return sp.technique == 0 ? frame.to_world(cosine_hemisphere(sp.u.x, sp.u.y)) : env_sample(env_map, opt, sp.u.x, sp.u.y);
  }
  std::pair<glm::vec3, double> operator()(int64_t t, int k, const SplitRotations& rot) const {
    const glm::vec3 d = direction(t, k, rot);
    if (!opt.importance_sampling) return {d, 1.0};  // w = π cancels
    const int N = opt.shadow_rays, n_cos = N / 2;
    const double c_cos = n_cos == 0 ? 0.5 : double(n_cos) / N;
    return {d, mixture_weight(d.y, c_cos, env_pdf(env_map, opt, d))};
  }
  // Inference with the radiance cache: operator() with the direction's panorama coordinates,
  // taken from the environment sample itself (no atan2/asin) when it is one.
  struct Ray {
    glm::vec3 d;
    double w;
    equirect::UV unit;
  };
  Ray cached(int64_t t, int k, const SplitRotations& rot) const {
    const int N = opt.shadow_rays, n_cos = N / 2;
    if (!opt.importance_sampling || n_cos == 0 || !opt.bilinear_env_sampling) {
      const auto [d, w] = (*this)(t, k, rot);
      return {d, w, equirect::direction_to_unit(d.x, d.y, d.z)};
    }
    const SplitSample sp = split_sample(rot, k, N, n_cos);
    Ray r;
    if (sp.technique == 0) {
      r.d = frame.to_world(cosine_hemisphere(sp.u.x, sp.u.y));
      r.unit = equirect::direction_to_unit(r.d.x, r.d.y, r.d.z);  // the bits of cached_all()'s batch
    } else {
      r.d = env_map.sample_bilinear_direction(sp.u.x, sp.u.y, r.unit);
    }
    r.w = mixture_weight(r.d.y, double(n_cos) / N, env_map.pdf_bilinear_unit(r.unit));
    return r;
  }
  // cached(t, k, rot) for every k < N into out[k], the cosine draws' panorama coordinates, the
  // sky's draws and all N densities each made as one batch (lanes: the same bits as one at a
  // time, without an atan2 and an asin, or a chain of divisions and square roots, per ray; the
  // sky's draws were 13% of the insertion under perf on an Intel Xeon).
  void cached_all(int64_t t, const SplitRotations& rot, Ray* out) const {
    const int N = opt.shadow_rays, n_cos = N / 2;
    if (!opt.importance_sampling || n_cos == 0 || !opt.bilinear_env_sampling) {
      for (int k = 0; k < N; ++k) out[k] = cached(t, k, rot);
      return;
    }
    static thread_local std::vector<float> u1, u2, pe;
    static thread_local std::vector<int> sky, cosine;
    static thread_local std::vector<glm::vec3> dirs;
    static thread_local std::vector<equirect::UV> units;
    u1.clear(), u2.clear(), sky.clear(), cosine.clear(), dirs.clear();
    for (int k = 0; k < N; ++k) {
      const SplitSample sp = split_sample(rot, k, N, n_cos);
      if (sp.technique == 0) {
        out[k].d = frame.to_world(cosine_hemisphere(sp.u.x, sp.u.y));
        dirs.push_back(out[k].d), cosine.push_back(k);
      } else {
        u1.push_back(sp.u.x), u2.push_back(sp.u.y), sky.push_back(k);
      }
    }
    const int n_sky = int(sky.size()), n_cosine = int(cosine.size());
    units.resize(size_t(std::max({N, n_sky, n_cosine}))), pe.resize(size_t(N));
    equirect::directions_to_units(n_cosine, dirs.data(), units.data());
    for (int j = 0; j < n_cosine; ++j) out[cosine[size_t(j)]].unit = units[size_t(j)];
    dirs.resize(size_t(n_sky));
    env_map.sample_bilinear_directions(n_sky, u1.data(), u2.data(), dirs.data(), units.data());
    for (int j = 0; j < n_sky; ++j) out[sky[size_t(j)]].d = dirs[size_t(j)], out[sky[size_t(j)]].unit = units[size_t(j)];
    for (int k = 0; k < N; ++k) units[size_t(k)] = out[k].unit;
    env_map.pdf_bilinear_units(N, units.data(), nullptr, pe.data());
    const double c_cos = double(n_cos) / N;
    for (int k = 0; k < N; ++k) out[k].w = mixture_weight(out[k].d.y, c_cos, pe[size_t(k)]);
  }
};

ShadowSampler make_sampler(const InsertionOptions& opt, const EnvironmentMap& env_map) {
  return ShadowSampler{opt, env_map, sample_seed(opt, kTagShadow), sample_seed(opt, kTagChoice + 1),
                       sample_seed(opt, kTagRotation + 1)};
}

}  // namespace

// Pass 1: which texels need rays (those with depth whose rays can meet the object's box).
std::vector<glm::vec3> shadow_texels(const InsertionInputs& in, const InsertionOptions& opt, const Bounds3& box,
                                     const EnvironmentMap& env_map, const double* depth, Shadows& sh,
                                     InsertionStats& stats) {
  const Camera& cam = in.camera;
  const int W = cam.intrinsics().width, H = cam.intrinsics().height;
  const int sw = opt.shadow_width, shh = opt.shadow_height, N = opt.shadow_rays;
  const int64_t n_texels = int64_t(sw) * shh;
  const ShadowSampler sampler = make_sampler(opt, env_map);
  const glm::vec3 up(0, 1, 0);
  sh.texel_depth.assign(size_t(n_texels), 0.0f);
  std::vector<glm::vec3> origin(static_cast<size_t>(n_texels));
  std::vector<uint8_t> needed(size_t(n_texels), 0);
  parallel_for(n_texels, 16, [&](int64_t b, int64_t e) {
    for (int64_t t = b; t < e; ++t) {
      const double u = (t % sw + 0.5) * W / sw, v = (t / sw + 0.5) * H / shh;
      const double d = depth[std::min<int64_t>(H - 1, int64_t(v)) * W + std::min<int64_t>(W - 1, int64_t(u))];
      if (!valid_depth(d)) continue;  // a hole (sky, missing depth): S = 1
      sh.texel_depth[size_t(t)] = float(d);
      const glm::vec3 x(cam.unproject(u, v, d));
      origin[size_t(t)] = x + ray_epsilon(x) * up;
      // Only rays with d.y > 0 carry weight; a box wholly below the origin meets none of them.
      if (opt.prune && box.hi.y <= origin[size_t(t)].y) continue;
      bool any = !opt.prune;
      const SplitRotations rot = sampler.rotations(t);
      for (int k = 0; k < N && !any; ++k) any = ray_hits_box(origin[size_t(t)], sampler.direction(t, k, rot), box);
      needed[size_t(t)] = any ? 1 : 0;  // none can meet the object: S = 1 exactly
    }
  });
  sh.texels.clear();
  for (int64_t t = 0; t < n_texels; ++t)
    if (needed[size_t(t)]) sh.texels.push_back(t);
  const int64_t count = int64_t(sh.texels.size());
  stats.shadow_pixels_total = n_texels;
  stats.shadow_pixels_computed = count;
  sh.offsets.resize(size_t(count) + 1);
  for (int64_t i = 0; i <= count; ++i) sh.offsets[size_t(i)] = i * N;
  return origin;
}

// Pass 2 writes their rays into fixed slots (the caller appends them after the light rays).
void trace_shadows(const InsertionInputs& in, const InsertionOptions& opt, const Bounds3& box, const Bvh& bvh,
                   const EnvironmentMap& env_map, const double* depth, Shadows& sh, QueryRays& rays,
                   InsertionStats& stats) {
  const std::vector<glm::vec3> origin = shadow_texels(in, opt, box, env_map, depth, sh, stats);
  const ShadowSampler sampler = make_sampler(opt, env_map);
  const glm::vec3 up(0, 1, 0);
  const int N = opt.shadow_rays;
  const int64_t count = int64_t(sh.texels.size());
  rays.resize(count * N);
  sh.visibility.assign(size_t(count * N), 1.0);
  sh.weights.assign(size_t(count * N), 0.0);
  parallel_for(count, 4, [&](int64_t b, int64_t e) {
    for (int64_t i = b; i < e; ++i) {
      const int64_t t = sh.texels[size_t(i)];
      const glm::vec3 o = origin[size_t(t)];
      const SplitRotations rot = sampler.rotations(t);
      for (int k = 0; k < N; ++k) {
        glm::vec3 dir;
        double w;
        if (opt.radiance_cache) {  // the directions shade_shadows() draws
          const ShadowSampler::Ray c = sampler.cached(t, k, rot);
          dir = c.d;
          w = c.w;
        } else {
          std::tie(dir, w) = sampler(t, k, rot);
        }
        const size_t slot = size_t(i * N + k);
        Ray r;
        r.origin = o;
        r.direction = dir;
        sh.visibility[slot] = w > 0 && bvh.occluded(r) ? opt.ambient : 1.0;
        sh.weights[slot] = w;
        rays.set(int64_t(slot), o, w > 0 ? dir : up);
      }
    }
  });
}

int64_t shade_shadows(const InsertionOptions& opt, const Bvh& bvh, const EnvironmentMap& env_map, const Shadows& sh,
                      const std::vector<glm::vec3>& origins, const RadianceCache& cache, double epsilon,
                      std::vector<float>& ratio, const RayMarcher* exact) {
  const ShadowSampler sampler = make_sampler(opt, env_map);
  const int N = opt.shadow_rays;
  const int M = exact ? std::min({opt.cache_shadow_exact_rays, N, kMaxCorrections}) : 0;
  static thread_local std::vector<glm::vec3> lc;  // a texel's cached radiance per ray (corrections)
  static thread_local std::vector<float> score, vis_of;
  static thread_local std::vector<ShadowSampler::Ray> drawn;  // a texel's rays
  static thread_local std::vector<double> visibility;         // and their V' of Eq. 4
  static thread_local std::vector<equirect::UV> units;        // of those with weight, their directions
  static thread_local std::vector<glm::vec3> radiance;        // and the cache's radiance
  static thread_local std::vector<float> exact_origins, exact_dirs;  // the corrections' rays
  static thread_local std::vector<RayMarcher::Result> exact_radiance;
  const uint64_t exact_seed = hash_counter(sample_seed(opt, kTagShadow), kTagExact);
  const int64_t count = int64_t(sh.texels.size());
  ratio.assign(size_t(3 * count), 1.0f);
  // With corrections: per texel the cached sums and the corrections relative to the denominator
  // (num/den, Δnum/den, Δden/den), filtered over neighbouring texels before S is formed.
  std::vector<glm::dvec3> base, fix_num, fix_den;
  if (M > 0) base.assign(size_t(count), glm::dvec3(1.0)), fix_num.assign(size_t(count), glm::dvec3(0.0)),
             fix_den.assign(size_t(count), glm::dvec3(0.0));
  std::atomic<int64_t> marched{0};
  // Dynamic: texels near the object and in the sun cost more (occlusion, exact marches).
  parallel_for_dynamic(count, 4, [&](int64_t b, int64_t e) {
    for (int64_t i = b; i < e; ++i) {
      const int64_t t = sh.texels[size_t(i)];
      const glm::vec3 o = origins[size_t(t)];
      double num[3] = {epsilon, epsilon, epsilon}, den[3] = {epsilon, epsilon, epsilon};
      double cnum[3] = {0, 0, 0}, cden[3] = {0, 0, 0};
      const RadianceCache::Corners at = cache.corners(&o[0]);
      int64_t here = 0;
      if (M > 0 && int(lc.size()) < N) lc.resize(size_t(N)), score.resize(size_t(N)), vis_of.resize(size_t(N));
      if (int(drawn.size()) < N) drawn.resize(size_t(N)), visibility.resize(size_t(N)), units.resize(size_t(N)), radiance.resize(size_t(N));
      // The rays and their occlusion first, then the cache's reads in ray order: each read is a
      // chain of 32 dependent FMAs, and with nothing else between them consecutive reads overlap
      // (interleaved with the sampling and the BVH they did not: perf, KITTI insertion bench).
      // Likewise all N draws, then their BVH tests: a traversal between two draws kept each draw's
      // chain of divisions and square roots (the sky's inverse CDF) from overlapping the next.
      const SplitRotations rot = sampler.rotations(t);
      sampler.cached_all(t, rot, drawn.data());
      for (int k = 0; k < N; ++k) {
        const ShadowSampler::Ray& s = drawn[size_t(k)];
        if (!(s.w > 0)) continue;
        Ray r;
        r.origin = o;
        r.direction = s.d;
        visibility[size_t(k)] = bvh.occluded(r) ? opt.ambient : 1.0;
      }
      // The cache reads of the rays with weight, its exact directions (the sun) marched together.
      int n_read = 0;
      for (int k = 0; k < N; ++k)
        if (drawn[size_t(k)].w > 0) units[size_t(n_read++)] = drawn[size_t(k)].unit;
      cache.radiance_units(at, units.data(), n_read, radiance.data());
      int read = 0;
      for (int k = 0; k < N; ++k) {
        const ShadowSampler::Ray& s = drawn[size_t(k)];
        if (M > 0) score[size_t(k)] = 0.0f;
        if (!(s.w > 0)) continue;  // weight 0: adds nothing to either sum
        const double vis = visibility[size_t(k)];
        const glm::vec3 L = radiance[size_t(read++)];
        for (int c = 0; c < 3; ++c) {
          num[c] += vis * s.w * L[c];
          den[c] += s.w * L[c];
        }
        if (M > 0) {
          lc[size_t(k)] = L;
          vis_of[size_t(k)] = float(vis);
          score[size_t(k)] = float(s.w * (std::abs(L.x) + std::abs(L.y) + std::abs(L.z)));
        }
      }
      if (M > 0) {
        // The exact correction (render/object_insertion.h): M of the N rays, drawn in proportion
        // to their cached light (render/exact_correction.h), for both sums.
        CorrectionPick picks[kMaxCorrections];
        const int m = pick_corrections(score.data(), N, M, uniform01f(exact_seed, uint64_t(t), 0), picks);
        // The picked rays with weight, marched together (RayMarcher's batch: the same bits).
        exact_origins.clear();
        exact_dirs.clear();
        for (int j = 0; j < m; ++j) {
          const ShadowSampler::Ray& s = drawn[size_t(picks[j].index)];
          if (!(s.w > 0)) continue;
          exact_origins.insert(exact_origins.end(), {o.x, o.y, o.z});
          exact_dirs.insert(exact_dirs.end(), {s.d.x, s.d.y, s.d.z});
        }
        const int64_t n_exact = int64_t(exact_dirs.size() / 3);
        exact_radiance.resize(size_t(n_exact));
        (*exact)(n_exact, exact_origins.data(), exact_dirs.data(), exact_radiance.data());
        int marched_j = 0;
        for (int j = 0; j < m; ++j) {
          const int k = picks[j].index;
          const ShadowSampler::Ray& s = drawn[size_t(k)];
          if (!(s.w > 0)) continue;
          ++here;
          const glm::vec3 d = exact_radiance[size_t(marched_j++)].radiance - lc[size_t(k)];
          if (all_finite(d))
            for (int c = 0; c < 3; ++c) {
              cnum[c] += picks[j].weight * vis_of[size_t(k)] * s.w * d[c];
              cden[c] += picks[j].weight * s.w * d[c];
            }
        }
      }
      if (M > 0) {
        for (int c = 0; c < 3; ++c) {
          base[size_t(i)][c] = num[c] / den[c];
          fix_num[size_t(i)][c] = cnum[c] / den[c];
          fix_den[size_t(i)][c] = cden[c] / den[c];
        }
      } else {
        for (int c = 0; c < 3; ++c) ratio[size_t(3 * i + c)] = float(num[c] / den[c]);
      }
      marched.fetch_add(here, std::memory_order_relaxed);
    }
  });
  if (M > 0) {
    // The corrections' noise is the cache's per-ray error, their mean the probes' bias, which
    // changes over a probe cell: averaged over the (2r+1)² neighbouring texels of similar depth
    // (σ = 5% of the texel's depth, as the upsampling), then S = (ρ + Δnum)/(1 + Δden) in [0, 1].
    const int sw = opt.shadow_width, shh = opt.shadow_height, rad = std::max(0, opt.cache_shadow_exact_filter_radius);
    std::vector<int64_t> slot(size_t(sw) * shh, -1);
    for (int64_t i = 0; i < count; ++i) slot[size_t(sh.texels[size_t(i)])] = i;
    parallel_for(count, 64, [&](int64_t b, int64_t e) {
      for (int64_t i = b; i < e; ++i) {
        const int64_t t = sh.texels[size_t(i)];
        const int tx = int(t % sw), ty = int(t / sw);
        const double dp = sh.texel_depth[size_t(t)];
        glm::dvec3 an(0.0), ad(0.0);
        double wsum = 0;
        for (int y = std::max(0, ty - rad); y <= std::min(shh - 1, ty + rad); ++y)
          for (int x = std::max(0, tx - rad); x <= std::min(sw - 1, tx + rad); ++x) {
            const int64_t j = slot[size_t(y) * sw + x];
            if (j < 0) continue;
            const double dq = sh.texel_depth[size_t(y) * sw + x];
            const double w = dp > 0 ? std::exp(-0.5 * std::pow((dp - dq) / (0.05 * dp), 2)) : double(j == i);
            if (!(w > 0)) continue;
            an += w * fix_num[size_t(j)];
            ad += w * fix_den[size_t(j)];
            wsum += w;
          }
        if (wsum > 0) an /= wsum, ad /= wsum;
        for (int c = 0; c < 3; ++c) {
          const double s = (base[size_t(i)][c] + an[c]) / std::max(1e-12, 1.0 + ad[c]);
          ratio[size_t(3 * i + c)] = float(std::isfinite(s) ? std::clamp(s, 0.0, 1.0) : base[size_t(i)][c]);
        }
      }
    });
  }
  return marched.load();
}

// Edge-aware upsampling taps:
// 4 bilinear texels per image pixel, weighted by depth similarity (σ = 5% of the pixel's depth),
// renormalised. Index `n_texels` is a constant-1 row for pixels with no depth.
void pixel_taps(const InsertionOptions& opt, const Shadows& sh, const double* depth, int W, int H, int row, int col,
                int64_t idx[4], double w[4]) {
  const int sw = opt.shadow_width, shh = opt.shadow_height;
  const int64_t one_row = int64_t(sw) * shh;
  const int64_t p = int64_t(row) * W + col;
  const double dp = depth[p];
  for (int c = 0; c < 4; ++c) {
    idx[c] = one_row;
    w[c] = 0.0;
  }
  if (!valid_depth(dp)) {
    w[0] = 1.0;
    return;
  }
  const double fx = (col + 0.5) * sw / W - 0.5, fy = (row + 0.5) * shh / H - 0.5;
  const int x0 = int(std::floor(fx)), y0 = int(std::floor(fy));
  const double ax = fx - x0, ay = fy - y0;
  double total = 0;
  for (int c = 0; c < 4; ++c) {
    const int x = std::clamp(x0 + (c & 1), 0, sw - 1), y = std::clamp(y0 + (c >> 1), 0, shh - 1);
    const int64_t t = int64_t(y) * sw + x;
    const double bil = ((c & 1) ? ax : 1 - ax) * ((c >> 1) ? ay : 1 - ay);
    const double dt = sh.texel_depth[t];
    const double sim = dt > 0 ? std::exp(-0.5 * std::pow((dp - dt) / (0.05 * dp), 2)) : 0.0;
    idx[c] = dt > 0 ? t : one_row;
    w[c] = bil * std::max(sim, 1e-12);
    total += w[c];
  }
  for (int c = 0; c < 4; ++c) w[c] = total > 0 ? w[c] / total : (c == 0 ? 1.0 : 0.0);
}

void upsample_taps(const InsertionInputs& in, const InsertionOptions& opt, const Shadows& sh, const double* depth,
                   std::vector<int64_t>& idx, std::vector<double>& w) {
  const int W = in.camera.intrinsics().width, H = in.camera.intrinsics().height;
  idx.assign(size_t(W) * H * 4, 0);
  w.assign(size_t(W) * H * 4, 0.0);
  parallel_for(H, 4, [&](int64_t r0, int64_t r1) {
    for (int row = int(r0); row < int(r1); ++row)
      for (int col = 0; col < W; ++col) {
        const int64_t p = int64_t(row) * W + col;
        pixel_taps(opt, sh, depth, W, H, row, col, &idx[size_t(4 * p)], &w[size_t(4 * p)]);
      }
  });
}

void upsample_shadows(const InsertionInputs& in, const InsertionOptions& opt, const Shadows& sh, const double* depth,
                      const std::vector<float>& ratio, std::vector<float>& s_img) {
  const int W = in.camera.intrinsics().width, H = in.camera.intrinsics().height;
  const int sw = opt.shadow_width, shh = opt.shadow_height;
  const int64_t n_texels = int64_t(sw) * shh;
  std::vector<float> texel(size_t(3 * (n_texels + 1)), 1.0f);  // S per texel; the extra row is the constant 1
  for (size_t i = 0; i < sh.texels.size(); ++i)
    for (int c = 0; c < 3; ++c) texel[size_t(3 * sh.texels[i] + c)] = ratio[3 * i + size_t(c)];
  // Rows and columns whose bilinear footprint meets a computed texel; every other pixel reads
  // texels of S = 1 only (weights sum to 1), so it is 1 exactly.
  int tx0 = sw, tx1 = -1, ty0 = shh, ty1 = -1;
  for (int64_t t : sh.texels) {
    tx0 = std::min(tx0, int(t % sw));
    tx1 = std::max(tx1, int(t % sw));
    ty0 = std::min(ty0, int(t / sw));
    ty1 = std::max(ty1, int(t / sw));
  }
  s_img.assign(size_t(3) * W * H, 1.0f);
  if (tx1 < 0) return;
  const int row0 = std::max(0, int(std::floor(double(ty0 - 1) * H / shh))), row1 = std::min(H, int(std::ceil(double(ty1 + 2) * H / shh)));
  const int col0 = std::max(0, int(std::floor(double(tx0 - 1) * W / sw))), col1 = std::min(W, int(std::ceil(double(tx1 + 2) * W / sw)));
  parallel_for(row1 - row0, 4, [&](int64_t r0, int64_t r1) {
    for (int row = row0 + int(r0); row < row0 + int(r1); ++row)
      for (int col = col0; col < col1; ++col) {
        int64_t idx[4];
        double w[4];
        pixel_taps(opt, sh, depth, W, H, row, col, idx, w);
        const int64_t p = int64_t(row) * W + col;
        for (int c = 0; c < 3; ++c) {
          double v = 0;
          for (int k = 0; k < 4; ++k) v += w[k] * texel[size_t(3 * idx[k] + c)];
          s_img[size_t(3 * p + c)] = float(v);
        }
      }
  });
}

}  // namespace sl::render::insertion
