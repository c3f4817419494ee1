// Differentiable virtual object insertion (Sec 3.3): foreground shading (Eq. 2), ratio shadow
// maps (Eq. 3-4) and compositing, as tape ops that let a loss on the composite move the lighting.
//
// Inputs: a background photo I (linear HDR [3, H, W]; linearise LDR first), its metric depth
// ([H, W], distance along the camera's z axis; 0, ±inf and NaN are holes), the camera, the
// lighting as tape variables — env [3, He, We] (the sky dome) and optionally vsg [8, X, Y, Z]
// (activated VSG parameters over `grid`) — and one or more objects already placed in the world
// frame (place_object() snaps a glTF mesh to the ground the depth map shows).
//
// Foreground (Eq. 2): aa_samples primary rays per pixel against the objects' BVH give fractional
// coverage; at each hit, light_samples directions l_k are shaded as
//   I_obj = (1/N) Σ_k L(x, l_k) f(v, l_k) (n·l_k) / p(l_k),
// with L the radiance query of Eq. 1 and f the Disney BRDF. Training mode draws l_k
// cosine-weighted over the hemisphere (as the paper draws them uniformly); inference mode
// (importance_sampling) combines BRDF and environment sampling with MIS. Directions blocked
// by the object itself see the ambient term I_a·L instead of L — the same rule as the shadow
// rays, so the object's self-shadowing and its cast shadow agree.
// Background (Eq. 3-4): each shadow-map pixel is lifted to 3D from the depth map with an upward
// normal; N_s upper-hemisphere directions are traced against the objects;
//   S = Σ_k w_k L'(x, l_k) / Σ_k w_k L(x, l_k),  L' = I_a·L where occluded, L elsewhere,
// w_k = cos/pdf. Training draws l_k cosine-weighted (w constant: plain averages, the paper's
// form); inference mixes cosine and environment sampling, so a hard sun that cosine samples
// would almost never hit still casts its shadow. S is differentiable
// through numerator and denominator. Guard: S = (Σ L' + ε)/(Σ L + ε) with ε = 1e-6·mean(L_env),
// so S → 1 as the light vanishes, never 0/0. The map is upsampled to the image edge-aware
// (bilateral in depth), then I_edit = α·I_obj + (1 − α)·(S ⊙ I), with α the object's coverage,
// and pixels whose depth is nearer than the object keep the photo (occlusion).
// Inference sampling (importance_sampling): the N light samples of a primary sample are split
// deterministically between the two techniques (multi-sample MIS, balance heuristic with
// n_brdf = ⌊N/2⌋) and stratified within each (a Hammersley set, Cranley-Patterson rotated per
// stream); shadow rays likewise split cosine and environment samples. Training mode keeps the
// independent cosine samples of the paper.
// Radiance cache (radiance_cache, inference): Eq. 1 splits into the volume's own radiance
// V(x, l) = Σ τ α G and its transmittance τ_K(x, l), with L = V + τ_K L_env(l). V and τ_K are
// queried once per probe (two grids, cache_spacing_m apart or sparser: at most cache_max_xz ×
// cache_max_y × cache_max_xz points (default 4×3×4) over the origins of the light rays, by default
// 2×2×2 over those of the shadow rays) and
// direction (cache_height × cache_width texel centres); a ray
// reads them trilinearly in position and bilinearly in direction, and L_env(l) exactly, so a
// sun in the sky keeps its full sharpness (render/radiance_cache.h). The object's light rays are
// then read as they are drawn and never stored (the foreground is off the tape in this mode).
// Sparse grids (cache_sparse): only the probes of cells that hold a ray's origin are marched
// (the object's visible shell, not its box); the values read are the dense grid's.
// Exact directions: a shadow ray toward sky brighter than cache_shadow_exact_sky × the sky's mean
// (the sun) is marched exactly instead (RayMarcher: radiance_query's value). The sun's
// transmittance changes over the ground faster than the probes follow, and the shadow ratio
// weighs it against the rest of the sky. Their cost is the share of shadow rays the sun draws
// (KITTI 000008: the released model's sky, 50k of 1M at 8×, shadow term 1.55% → 1.05% for +5%
// CPU; the bench's sharp HDRI sun over a random volume, 313k, 1.36% → 1.28% for +70%).
// Error against exact queries: streetlight-bench insert.
// Exact corrections (cache_exact_light_rays, cache_shadow_exact_rays): the probes' trilinear read
// of a volume looked up at its nearest voxel is biased wherever the volume changes within a probe
// cell, and finer probes lower that bias slowly (KITTI 000008, released lighting: the object term
// 1.24% at the default grid, 0.98% at 0.5 m, 0.91% at 0.35 m for +76% CPU). Instead, M of a
// sample's N rays, drawn in proportion to their cached contribution (render/exact_correction.h),
// are also marched exactly, and Σ w·(L_exact − L_cached)/(M·p) is added: the cached sum's
// expectation plus that of the correction is the exact one (M ≥ N: every ray, exactly). The
// control variate is untouched (its g-term reads the cache on both sides). The correction's
// noise is the cache's per-ray error, large beside its mean, so it is smoothed like the residual
// (render/insertion_denoise.h, without the noise guide) over cache_exact_filter_radius; that
// filter's bias is what it leaves. Shadows: the numerator and the denominator of S each get the
// correction of the same rays, relative to the denominator and averaged over the texels within
// cache_shadow_exact_filter_radius of similar depth, then S = (ρ + Δnum)/(1 + Δden) in [0, 1].
// Measured: streetlight-bench insert, rows exact_* (train/photo_insertion.h has the figures).
// Lean: shadows are computed only inside the screen-space region the object can shadow (its
// bounds swept along the light directions that carry energy, clipped to the image) and shading
// only inside the object's screen bounds. stats reports the fraction skipped; the result equals
// the unpruned one (tested).
// Control variate (diffuse_control_variate, with the radiance cache): Eq. 2 splits as
//   I_obj = ∫ g cos L dΩ + (1/N) Σ_k [f(v, l_k)·V'(l_k) − g(l_k)] (n·l_k) L(x, l_k) / p(l_k),
// V' = 1 or I_a where the object blocks l_k, and g Burley's diffuse lobe with F_D90 fixed at a
// horizon light's azimuthal mean (disney::diffuse_control): g = c·(1 + κ(1 − n·l)^5), so
// ∫ g cos L = c·(E(x, n) + κ E₅(x, n)), E the irradiance of the cached radiance and E₅ the same
// with the extra (1 − n·l)^5. Both are integrated once per probe (one matrix product over a
// quadrature grid twice the env's resolution) for the nodes of a grid of normals the samples
// touch, and read trilinearly × bilinearly like L. Where the object does not block the sky the
// sum is small, so most of the sun's and sky's sampling noise leaves the diffuse shading; the
// bias is E's quadrature and normal-grid interpolation (streetlight-bench insert, rows cv_*).
// Adaptive sampling (adaptive_light_samples > 0, with the radiance cache): a second pass of
// Eq. 2's sum where the first is noisy. From the first pass's N samples per primary sample, each
// pixel's spread s: the standard deviation of one light sample's term (summed over channels),
// averaged over its 3×3 object neighbours with the pixel itself left out. The error over the
// image, Σ s²/(N + m), is least for a fixed number of extra rays when N + m ∝ s, so each pixel
// gets m = clamp(t·s − N, 0, adaptive_max_factor·N) more per primary sample (rounded to even),
// t set so that the extra rays average adaptive_light_samples per visible primary sample. The
// m samples are a fresh stratified set (their own seeds), and the pixel's sum is
// (N·first + m·second)/(N + m). Since m does not depend on the pixel's own first pass, the
// blend is unbiased (tested: AdaptiveSampling.KeepsTheMeanAtTheSameNumberOfRays).
// Denoising (denoise_radius > 0, with the control variate): the sampled residual R of each
// pixel (Eq. 2 less ∫g·cos·L) is smoothed as a ratio to the control's noise-free C over a small
// window guided by normals, depth and the ratio's own noise (render/insertion_denoise.h); C
// itself, the coverage and the shadows are untouched. It trades noise for a bias where the
// object's self-occlusion or specular changes faster than the guides see (measured:
// streetlight-bench insert, rows denoise*).
// Every op is one tape node per call; backward recomputes its rays and samples.
#pragma once
#include <cstdint>
#include <memory>
#include <vector>

#include "autodiff/tensor.h"
#include "render/bvh.h"
#include "render/camera.h"
#include "render/mesh.h"
#include "render/object_placement.h"
#include "render/radiance_query.h"

namespace sl::render {

struct InsertionOptions {
  int aa_samples = 4;           // primary rays per pixel
  int light_samples = 64;       // N of Eq. 2 per visible primary sample...
  int64_t foreground_rays = 0;  // ...or, when > 0, a total budget spread over them (training; the paper uses 5000)
  int shadow_width = 80, shadow_height = 45;
  int shadow_rays = 128;        // N_s of Eq. 4
  double ambient = 0.1;         // I_a
  bool importance_sampling = false;  // inference: BRDF + environment MIS
  // Inference: environment samples follow the bilinear lookup itself (EnvironmentMap::
  // sample_bilinear, L_env/pdf nearly constant: a sun over a few texels costs almost no
  // variance) instead of piecewise-constant texels (EnvironmentMap::sample). Both unbiased.
  bool bilinear_env_sampling = false;
  // Inference: the aa_samples × N light samples of a pixel form one stratified set (interleaved
  // over its primary samples) rather than aa_samples independent sets of N. Unbiased; with the
  // control variate it raised the noise under a strong sun (train/photo_insertion.h), so the
  // photo defaults leave it off.
  bool stratify_per_pixel = false;
  bool prune = true;            // skip pixels the object cannot affect
  uint64_t seed = 0;            // anti-aliasing jitter, and (with lighting_seed 0) every other sample
  uint64_t lighting_seed = 0;   // != 0: light and shadow samples drawn independently of `seed`
  RadianceQueryOptions query;
  // Inference only (throws when env or vsg requires a gradient): light and shadow rays read the
  // volume through probes instead of each marching it (see "Radiance cache" above).
  bool radiance_cache = false;
  int cache_height = 32, cache_width = 64;  // probe directions (equirect texel centres)
  double cache_spacing_m = 2.0;             // probe spacing over the rays' origins...
  int cache_max_xz = 4, cache_max_y = 3;    // ...with at most this many probes per horizontal axis / vertically (light rays)
  int cache_shadow_max_xz = 2, cache_shadow_max_y = 2;  // the same for the shadow rays' grid
  int cache_shadow_height = 0;  // > 0: the shadow grid's directions, cache_shadow_height × 2·that (else as above)
  // Both grids build only the probes of cells that hold a ray's origin (render/radiance_cache.h,
  // sparse): the same values where rays read, fewer marches (Lean; tested).
  bool cache_sparse = true;
  // Shadow rays whose sky radiance L_env(l) (largest channel) exceeds this multiple of the sky's
  // mean radiance are marched exactly rather than read from the probes (see "Radiance cache");
  // 0 = none.
  double cache_shadow_exact_sky = 8.0;
  // Exact corrections (see "Exact corrections" above): per primary sample of the object, this
  // many of its N light rays are also marched exactly, and N/M·w·(L_exact − L_cached) is added to
  // its sum; per shadow texel, cache_shadow_exact_rays of its rays likewise. 0 = none.
  int cache_exact_light_rays = 0;
  int cache_shadow_exact_rays = 0;
  int cache_exact_filter_radius = 8;  // the object's correction is smoothed over (2r+1)² pixels (0 = not)
  int cache_shadow_exact_filter_radius = 3;  // the shadows' over (2r+1)² texels of the shadow map
  // Inference, with the radiance cache: Eq. 2 with the Lambertian part of the BRDF as a control
  // variate (see "Control variate" above): E on a grid of cv_normals_height × 2·height normals,
  // integrated over square texels half the env's rows high, refined cv_quadrature_supersample× per axis.
  bool diffuse_control_variate = false;
  // 128 rows since 2026-11-27: under a strong sun near the zenith, a vertical face sits at the
  // terminator of E, whose kink bilinear reads smooth out (KITTI 000008 with release 0.6.0,
  // streetlight-bench insert rows cv_normals*: 64 rows 2.10%, 96 1.61%, 128 1.50%, 256 1.43%; the
  // weak sun of an earlier release (2026-11-26) 0.93% at every height; +18 ms).
  int cv_normals_height = 128, cv_quadrature_supersample = 1;
  // Inference, with the radiance cache: adaptive light samples (see "Adaptive sampling" above).
  // On average adaptive_light_samples more per visible primary sample, at most
  // adaptive_max_factor·N more per pixel's primary sample; 0 = off.
  double adaptive_light_samples = 0;
  int adaptive_max_factor = 8;
  // Inference, with the radiance cache and the control variate: the residual filter (see
  // "Denoising" above) over a (2·denoise_radius + 1)² window; 0 = off. Its guides: normals
  // (1 − n·n' over denoise_normal_sigma), the distance from the pixel's tangent plane relative to
  // its depth (over denoise_depth_sigma), and the residual's ratio to the control in units of its
  // noise (denoise_variance_sigma; 0 = unused).
  int denoise_radius = 0;
  double denoise_normal_sigma = 0.02, denoise_depth_sigma = 0.003, denoise_variance_sigma = 4.0;
};

struct InsertionStats {
  int64_t shadow_pixels_total = 0, shadow_pixels_computed = 0;
  int64_t image_pixels_total = 0, foreground_pixels_shaded = 0;
  int64_t foreground_samples = 0;  // primary rays that see the object (the "foreground rays")
  int64_t query_rays = 0;          // rays sent to the radiance query (light + shadow)
  int64_t adaptive_light_rays = 0; // of those, the light rays adaptive sampling added
  int64_t exact_query_rays = 0;    // of those, with the radiance cache: rays marched exactly (exact directions)
  int64_t exact_correction_rays = 0;  // with the radiance cache: rays marched for the exact corrections
};

struct InsertionResult {
  Tensor composite;     // [3, H, W]
  Tensor object_mask;   // [1, H, W] coverage α in [0, 1]
  Tensor shadow_map;    // [3, H, W] S per channel at image resolution (1 where unaffected)
  Tensor object_depth;  // [1, H, W] camera-z depth of the object (0 where absent)
  Tensor object_silhouette;  // [1, H, W] coverage ignoring the photo's depth (α before occlusion)
  InsertionStats stats;
};

struct InsertionInputs {
  Tensor background;  // [3, H, W] linear HDR
  Tensor depth;       // [H, W]
  Camera camera;
  Tensor env;         // [3, He, We]
  Tensor vsg;         // [8, X, Y, Z] or undefined (sky only)
  VsgGrid grid;
  std::vector<PlacedObject> objects;
};

InsertionResult insert_objects(const InsertionInputs& inputs, const InsertionOptions& options = {});

}  // namespace sl::render
