// The radiance query L(x, l) of Eq. 1, as ONE fused tape op over a batch of rays:
//
//   L(x, l) = Σ_{k=1..K} τ_{k−1} α_k G(−l; ξ_k) + τ_K L_env(l),   τ_k = Π_{i≤k} (1 − α_i)
//
// Inputs: vsg [N, 8, X, Y, Z] (activated parameters, see vsg_volume.h), env [N, 3, H, W]
// (panorama convention of equirect.h), origins and directions [N, R, 3] (world). The unbatched
// forms [8, X, Y, Z], [3, H, W], [R, 3] are accepted too. Directions are normalised here; a zero
// or non-finite ray gives radiance 0, τ_K = 1, depth 0 and no gradient.
// Samples over the part [t0, t1] of the ray inside the grid's box (none when it misses the box):
//   - spacing kMetric: K equi-spaced points t_k = t0 + (k − ½)(t1 − t0)/K (even in metres);
//   - spacing kGrid: K points equi-spaced in voxel coordinates — the k-th sits where the ray's
//     arc length through the log-projected grid (vsg_volume.h) reaches (k − ½)/K of its total, so
//     the small voxels near the camera are not skipped and the large outer ones not oversampled.
//     The arc length ∫ |dv/dt| dt, with dv_a/dt = k±_a l_a / (r0 + |d_a|) per voxel axis a, is
//     integrated by the trapezoid rule on 4K sub-intervals and inverted linearly (a deterministic
//     function of the ray, recomputed identically by backward).
//     With nearest lookup, a sample in the same voxel as the previous sample is skipped, so each
//     voxel crossed is composited once however large K is (K → ∞ converges to the exact
//     one-composite-per-voxel march; evenly spaced samples composite a voxel once per sample).
// Lookup: nearest voxel (the paper) or trilinear (α and G interpolated separately, borders clamped).
// Outputs: radiance [N, R, 3]; transmittance τ_K [N, R] (for the sky-separation loss); depth
// [N, R] = Σ τ_{k−1} α_k t_k, the expected distance of the volume's contribution (unnormalised:
// divide by 1 − τ_K for the depth of the visible surface).
// Gradients flow to vsg and env (not to origins or directions). Backward recomputes the samples
// (nothing per sample is stored) and uses the stable recursion B_{k−1} = α_k g_k + (1 − α_k) B_k,
// ∂L/∂α_k = τ_{k−1}(g_k − B_k), so α = 1 is safe. Gradients are scattered into a fixed number of
// per-chunk buffers summed in order: identical bits for any thread count.
//
// Pruning (opt.prune, on by default) — the pruned query is a slightly different function, and
// backward differentiates exactly that function:
//   - a sample whose α_k < empty_alpha is skipped (treated as α_k = 0): error ≤ empty_alpha·G;
//   - a ray stops once τ_k · max(1, max_c L_env,c(l)) < min_transmittance, dropping the rest of
//     the volume and the sky term: error ≤ min_transmittance · (1 + G_max / max(1, L_env)).
//     Scaling by the sky's radiance keeps a 10^5 sun behind a nearly opaque wall from leaking.
// tests/render/radiance_query_test.cpp checks pruned against unpruned within these bounds.
#pragma once
#include <cstdint>
#include <memory>
#include <string>

#include "autodiff/tape.h"
#include "render/vsg_volume.h"

namespace sl::render {

// Where Eq. 1's K samples sit along a ray (see "Samples" above).
enum class SampleSpacing { kMetric, kGrid };
SampleSpacing parse_sample_spacing(const std::string& name);  // "metric" | "grid"; throws naming it
const char* sample_spacing_name(SampleSpacing spacing);

struct RadianceQueryOptions {
  int samples = 64;                 // K
  SampleSpacing spacing = SampleSpacing::kMetric;
  bool trilinear = false;           // nearest voxel (paper) or trilinear
  bool prune = true;
  double empty_alpha = 1e-6;
  double min_transmittance = 1e-4;
};

struct RadianceQueryStats {
  int64_t rays = 0;
  int64_t samples_total = 0;      // rays × K, over rays that hit the grid
  int64_t samples_evaluated = 0;  // lobes actually evaluated
  int64_t rays_terminated = 0;    // stopped early by transmittance
};

struct RadianceQueryResult {
  Tensor radiance;       // [N, R, 3] (or [R, 3])
  Tensor transmittance;  // [N, R]    (or [R])
  Tensor depth;          // [N, R]    (or [R])
};

RadianceQueryResult radiance_query(const Tensor& vsg, const Tensor& env, const Tensor& origins,
                                   const Tensor& directions, const VsgGrid& grid,
                                   const RadianceQueryOptions& options = {}, RadianceQueryStats* stats = nullptr);

// One ray at a time, off the tape: the forward of radiance_query() (float32) for callers that
// need a few exact rays among many cached ones (render/radiance_cache.h, exact directions). The
// same march and the same sums, so the same bits as radiance_query() on float32 inputs; no
// stats. vsg [8, X, Y, Z] matching grid.dims, env [3, H, W]; both are copied to float32 once
// (the volume as one record per voxel, which a march reads as one cache line per sample).
// Thread-safe (scratch is per thread).
class RayMarcher {
 public:
  RayMarcher(const Tensor& vsg, const Tensor& env, const VsgGrid& grid, const RadianceQueryOptions& options);
  struct Result {
    glm::vec3 radiance{0.0f};
    float transmittance = 1.0f;  // τ_K
  };
  Result operator()(const float origin[3], const float dir[3]) const;
  // n rays at once: out[i] = (*this)(origins + 3·i, dirs + 3·i), the same bits. With nearest
  // lookup on AVX-512, 16 rays at a time share vector lanes from their samples' α on (the
  // sequential sums of Eq. 1 run side by side); otherwise one ray after the other.
  void operator()(int64_t n, const float* origins, const float* dirs, Result* out) const;

 private:
  void march_lanes(int64_t n, const float* origins, const float* dirs, Result* out) const;  // AVX-512
  struct Projection;  // the grid's log projection, precomputed once
  struct Voxels;      // the volume, one record per voxel (radiance_query.cpp: InterleavedVolume)
  Tensor env_;
  VsgGrid grid_;
  RadianceQueryOptions opt_;
  std::shared_ptr<const Projection> proj_;
  std::shared_ptr<const Voxels> voxels_;
};

}  // namespace sl::render
