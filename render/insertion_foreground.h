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

namespace sl::render::insertion {

struct Foreground {
  std::vector<int64_t> pixels;   // image pixels with at least one visible sample
  std::vector<int64_t> offsets;  // per pixel, into the light rays
  std::vector<float> weights;    // 3 per light ray: f·cos/pdf / (N·aa), × I_a when self-occluded
  std::vector<float> coverage, depth;  // per image pixel
  std::vector<float> silhouette;       // per image pixel: coverage before the photo's occlusion
  int light_samples = 0;         // N actually used
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
void trace_foreground(const InsertionOptions& opt, const Bvh& bvh, const EnvironmentMap& env_map,
                      const std::vector<GSample>& gs, Foreground& fg, QueryRays& rays);

}  // namespace sl::render::insertion
