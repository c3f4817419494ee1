// The background of object insertion, Eq. 3-4 (Sec 3.3): the ratio shadow map. Each texel of
// a low-resolution map is lifted to 3D from the depth map with an upward normal and sends N_s
// shadow rays l_k over the upper hemisphere;
//   S = Σ_k w_k L'(x, l_k) / Σ_k w_k L(x, l_k),   L' = I_a·L where the object occludes l_k,
// with w_k = cos/pdf, evaluated by shadow_ratio (render/insertion_ops.h) on the one radiance
// query's output; the map is then upsampled to the image edge-aware (bilateral in depth).
// render/object_insertion.h states the sampling and the ε guard. Internal to render/.
//
// Contract: trace_shadows() computes only texels whose rays can meet the object's box (the
// rest stay S = 1; equal to computing them, tested) and writes their rays in texel order;
// upsample_taps() gives 4 weighted taps per image pixel, index n_texels being a constant-1 row.
#pragma once
#include <cstdint>
#include <vector>

#include "render/bvh.h"
#include "render/environment_map.h"
#include "render/insertion_rays.h"
#include "render/object_insertion.h"
#include "render/radiance_cache.h"

namespace sl::render::insertion {

struct Shadows {
  std::vector<int64_t> texels;   // shadow-map texels computed
  std::vector<int64_t> offsets;  // per texel, into the shadow rays (relative to their start)
  std::vector<double> visibility;
  std::vector<double> weights;       // cos/pdf per shadow ray
  std::vector<float> texel_depth;  // per texel of the whole map (0 = hole)
};

// Pass 1 decides which texels need rays (those with depth whose rays can meet the object's box):
// sh.texels, sh.texel_depth, sh.offsets and the stats; returns the ray origin of every texel.
std::vector<glm::vec3> shadow_texels(const InsertionInputs& in, const InsertionOptions& opt, const Bounds3& box,
                                     const EnvironmentMap& env_map, const double* depth, Shadows& sh,
                                     InsertionStats& stats);
// Pass 1, then pass 2 writes their rays into fixed slots (the caller appends them after the
// light rays).
void trace_shadows(const InsertionInputs& in, const InsertionOptions& opt, const Bounds3& box, const Bvh& bvh,
                   const EnvironmentMap& env_map, const double* depth, Shadows& sh, QueryRays& rays,
                   InsertionStats& stats);
// Inference with the radiance cache, after shadow_texels(): S of Eq. 4 for each texel of
// sh.texels (3 floats each, in that order), every ray read from `cache` as it is drawn (no ray
// buffer); the same sums as trace_shadows() + the cache's reads + shadow_ratio (tested).
// With `exact` and opt.cache_shadow_exact_rays > 0, both sums get the exact correction
// (render/object_insertion.h, "Exact corrections") and S is clamped to [0, 1]; returns the rays
// marched for it.
int64_t shade_shadows(const InsertionOptions& opt, const Bvh& bvh, const EnvironmentMap& env_map, const Shadows& sh,
                   const std::vector<glm::vec3>& origins, const RadianceCache& cache, double epsilon,
                   std::vector<float>& ratio, const RayMarcher* exact = nullptr);
// Edge-aware upsampling taps: 4 bilinear texels per image pixel, weighted by depth similarity
// (σ = 5% of the pixel's depth), renormalised. Index `n_texels` is a constant-1 row for pixels
// with no depth.
void upsample_taps(const InsertionInputs& in, const InsertionOptions& opt, const Shadows& sh, const double* depth,
                   std::vector<int64_t>& idx, std::vector<double>& w);
// Inference: the same upsampling of S given per computed texel (`ratio`, as shade_shadows()
// gives it) into s_img [H·W, 3], visiting only pixels whose taps can meet a computed texel (the
// rest are 1 exactly).
void upsample_shadows(const InsertionInputs& in, const InsertionOptions& opt, const Shadows& sh, const double* depth,
                      const std::vector<float>& ratio, std::vector<float>& s_img);

}  // namespace sl::render::insertion
