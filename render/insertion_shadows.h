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

namespace sl::render::insertion {

struct Shadows {
  std::vector<int64_t> texels;   // shadow-map texels computed
  std::vector<int64_t> offsets;  // per texel, into the shadow rays (relative to their start)
  std::vector<double> visibility;
  std::vector<double> weights;       // cos/pdf per shadow ray
  std::vector<float> texel_depth;  // per texel of the whole map (0 = hole)
};

// Pass 1 decides which texels need rays (those with depth whose rays can meet the object's box);
// pass 2 writes their rays into fixed slots (the caller appends them after the light rays).
void trace_shadows(const InsertionInputs& in, const InsertionOptions& opt, const Bounds3& box, const Bvh& bvh,
                   const EnvironmentMap& env_map, const double* depth, Shadows& sh, QueryRays& rays,
                   InsertionStats& stats);
// Edge-aware upsampling taps: 4 bilinear texels per image pixel, weighted by depth similarity
// (σ = 5% of the pixel's depth), renormalised. Index `n_texels` is a constant-1 row for pixels
// with no depth.
void upsample_taps(const InsertionInputs& in, const InsertionOptions& opt, const Shadows& sh, const double* depth,
                   std::vector<int64_t>& idx, std::vector<double>& w);

}  // namespace sl::render::insertion
