// The foreground of object insertion, Eq. 2 (Sec 3.3): primary rays against the objects give
// a G-buffer and fractional coverage; each visible sample then gets N light directions,
//   I_obj = (1/N) Σ_k L(x, l_k) f(v, l_k) (n·l_k) / p(l_k),
// whose rays (into the shared buffer) and weights f·cos/pdf/(N·aa) are what the one radiance
// query and weighted_segment_sum (render/insertion_ops.h) turn into the object's colour.
// render/object_insertion.h states the sampling (training: cosine; inference: BRDF + environment
// MIS) and the ambient rule for self-occluded directions. Internal to render/.
//
// Contract: gbuffer() fills fg.coverage, fg.depth and fg.silhouette for every image pixel and
// returns the visible samples; trace_foreground() writes sample i's rays to slots [i·N, (i+1)·N)
// of `rays` (already sized) and their weights, so the result is the same for any thread count.
#pragma once
#include <cstdint>
#include <vector>

#include <glm/glm.hpp>

#include "render/bvh.h"
#include "render/disney_brdf.h"
#include "render/environment_map.h"
#include "render/insertion_rays.h"
#include "render/mesh.h"
#include "render/object_insertion.h"
#include "render/radiance_cache.h"

namespace sl::render::insertion {

struct Foreground {
  std::vector<int64_t> pixels;   // image pixels with at least one visible sample
  std::vector<int64_t> offsets;  // per pixel, into the light rays
  std::vector<float> weights;    // 3 per light ray: f·cos/pdf / (N·aa), × I_a when self-occluded
  std::vector<float> coverage, depth;  // per image pixel
  std::vector<float> silhouette;       // per image pixel: coverage before the photo's occlusion
  int light_samples = 0;         // N actually used
  int64_t width = 0;             // the image's, for pixel neighbourhoods
  int64_t exact_correction_rays = 0;  // marched for opt.cache_exact_light_rays (shade_foreground, with `exact`)
  int64_t extra_light_rays = 0;  // adaptive sampling's second pass (shade_foreground)
};

// A visible primary sample: the G-buffer entry of Eq. 2.
struct GSample {
  int64_t pixel;
  uint64_t stream;  // counter-RNG stream of its light samples
  glm::vec3 x, n, wo;
  disney::Params material;
};

// Pass 1: primary rays against the objects, in parallel over image rows.
std::vector<GSample> gbuffer(const InsertionInputs& in, const InsertionOptions& opt, const Mesh& mesh, const Bvh& bvh,
                             const double* depth, Foreground& fg, InsertionStats& stats);
// Pass 2: N light directions per G-buffer sample, written to fixed slots [i·N, (i+1)·N).
// The origin of a sample's light rays (offset along its normal).
inline glm::vec3 light_origin(const GSample& g) { return g.x + ray_epsilon(g.x) * g.n; }

// With control_variate, each weight is less g(l)·cos/pdf/(N·aa) (g of disney::diffuse_control:
// the residual of render/object_insertion.h's "Control variate"); shade_foreground() adds ∫g·cos·L/aa.
void trace_foreground(const InsertionOptions& opt, const Bvh& bvh, const EnvironmentMap& env_map,
                      const std::vector<GSample>& gs, Foreground& fg, QueryRays& rays, bool control_variate = false);
// Inference with the radiance cache: the same light rays, read from `cache` as they are drawn
// (no ray buffer); `colour` gets Σ w·L per pixel of fg.pixels (3 floats each), plus ∫g·cos·L/aa per
// sample with the control variate (cache.build_irradiance() done for the samples' normals),
// clamped at 0.
// With opt.adaptive_light_samples > 0, a second pass adds light samples where the first was noisy
// (render/object_insertion.h, "Adaptive sampling"); with opt.denoise_radius > 0 and the control
// variate, the residual is filtered (render/insertion_denoise.h). Both off: equal to
// trace_foreground() followed by the cache's reads and weighted_segment_sum (tested).
void shade_foreground(const InsertionOptions& opt, const Bvh& bvh, const EnvironmentMap& env_map,
                      const std::vector<GSample>& gs, const RadianceCache& cache, bool control_variate, Foreground& fg,
                      std::vector<float>& colour, const RayMarcher* exact = nullptr);

// Adaptive sampling's allocation: per pixel, the extra light samples m per primary sample that
// minimise Σ s²/(N + m) for Σ visible·m ≈ budget: m = clamp(t·s − N, 0, cap) rounded to even,
// t found by bisection (the largest t whose unrounded cost fits the budget). spread s ≥ 0
// (non-finite counts as 0), visible = the pixel's visible primary samples.
std::vector<int> adaptive_extra_samples(const std::vector<double>& spread, const std::vector<int>& visible, int N,
                                        double budget, int cap);

}  // namespace sl::render::insertion
