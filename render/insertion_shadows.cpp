// Eq. 3-4: the shadow rays and the edge-aware upsampling of the ratio shadow map (see
// insertion_shadows.h).
#include "render/insertion_shadows.h"

#include <algorithm>
#include <cmath>

#include "render/equirect.h"
#include "render/sampling.h"
#include "util/math.h"
#include "util/parallel.h"
#include "util/random.h"

namespace sl::render::insertion {
namespace {

// The k-th shadow direction of texel t and its weight cos/pdf (0 marks an unusable sample).
struct ShadowSampler {
  const InsertionOptions& opt;
  const EnvironmentMap& env_map;
  uint64_t seed, choice_seed, rot_seed;
  Frame frame{glm::vec3(0, 1, 0)};
  // The direction alone (what the texel pruning needs: no density).
  glm::vec3 direction(int64_t t, int k) const {
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
    const SplitSample sp = split_sample(rot_seed, uint64_t(t), k, N, n_cos);
    return sp.technique == 0 ? frame.to_world(cosine_hemisphere(sp.u.x, sp.u.y)) : env_sample(env_map, opt, sp.u.x, sp.u.y);
  }
  std::pair<glm::vec3, double> operator()(int64_t t, int k) const {
    const glm::vec3 d = direction(t, k);
    if (!opt.importance_sampling) return {d, 1.0};  // w = π cancels
    const int N = opt.shadow_rays, n_cos = N / 2;
    const double c_cos = n_cos == 0 ? 0.5 : double(n_cos) / N;
    const double cos_t = d.y, pdf = c_cos * std::max(0.0, cos_t) / kPi + (1.0 - c_cos) * env_pdf(env_map, opt, d);
    return {d, (cos_t > 0 && pdf > 0) ? cos_t / pdf : 0.0};
  }
};

}  // namespace

// Pass 1 decides which texels need rays (those with depth whose rays can meet the object's box);
// pass 2 writes their rays into fixed slots (the caller appends them after the light rays).
void trace_shadows(const InsertionInputs& in, const InsertionOptions& opt, const Bounds3& box, const Bvh& bvh,
                   const EnvironmentMap& env_map, const double* depth, Shadows& sh, QueryRays& rays,
                   InsertionStats& stats) {
  const Camera& cam = in.camera;
  const int W = cam.intrinsics().width, H = cam.intrinsics().height;
  const int sw = opt.shadow_width, shh = opt.shadow_height, N = opt.shadow_rays;
  const int64_t n_texels = int64_t(sw) * shh;
  const ShadowSampler sampler{opt, env_map, sample_seed(opt, kTagShadow), sample_seed(opt, kTagChoice + 1),
                              sample_seed(opt, kTagRotation + 1)};
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
      for (int k = 0; k < N && !any; ++k) any = ray_hits_box(origin[size_t(t)], sampler.direction(t, k), box);
      needed[size_t(t)] = any ? 1 : 0;  // none can meet the object: S = 1 exactly
    }
  });
  for (int64_t t = 0; t < n_texels; ++t)
    if (needed[size_t(t)]) sh.texels.push_back(t);
  const int64_t count = int64_t(sh.texels.size());
  stats.shadow_pixels_total = n_texels;
  stats.shadow_pixels_computed = count;
  sh.offsets.resize(size_t(count) + 1);
  for (int64_t i = 0; i <= count; ++i) sh.offsets[size_t(i)] = i * N;
  rays.resize(count * N);
  sh.visibility.assign(size_t(count * N), 1.0);
  sh.weights.assign(size_t(count * N), 0.0);
  parallel_for(count, 4, [&](int64_t b, int64_t e) {
    for (int64_t i = b; i < e; ++i) {
      const int64_t t = sh.texels[size_t(i)];
      const glm::vec3 o = origin[size_t(t)];
      for (int k = 0; k < N; ++k) {
        const auto [dir, w] = sampler(t, k);
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

// Edge-aware upsampling taps: 4 bilinear texels per image pixel, weighted by depth similarity
// (σ = 5% of the pixel's depth), renormalised. Index `n_texels` is a constant-1 row for pixels
// with no depth.
void upsample_taps(const InsertionInputs& in, const InsertionOptions& opt, const Shadows& sh, const double* depth,
                   std::vector<int64_t>& idx, std::vector<double>& w) {
  const int W = in.camera.intrinsics().width, H = in.camera.intrinsics().height;
  const int sw = opt.shadow_width, shh = opt.shadow_height;
  const int64_t one_row = int64_t(sw) * shh;
  idx.assign(size_t(W) * H * 4, one_row);
  w.assign(size_t(W) * H * 4, 0.0);
  parallel_for(H, 4, [&](int64_t r0, int64_t r1) {
    for (int row = int(r0); row < int(r1); ++row)
      for (int col = 0; col < W; ++col) {
        const int64_t p = int64_t(row) * W + col;
        const double dp = depth[p];
        if (!valid_depth(dp)) {
          w[4 * p] = 1.0;
          continue;
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
          idx[4 * p + c] = dt > 0 ? t : one_row;
          w[4 * p + c] = bil * std::max(sim, 1e-12);
          total += w[4 * p + c];
        }
        for (int c = 0; c < 4; ++c) w[4 * p + c] = total > 0 ? w[4 * p + c] / total : (c == 0 ? 1.0 : 0.0);
      }
  });
}

}  // namespace sl::render::insertion
