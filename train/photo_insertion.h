// Inserting a glTF object into a photograph with estimated lighting (Sec 3.3 at inference):
// the glue between train/inference.h (the lighting, in view 0's canonical frame) and
// render/object_insertion.h (Eq. 2-4), plus the depth sources a photo can have.
//
// Contract:
// - ground_plane_depth(camera): camera-z depth of the plane y = 0 for every pixel whose ray
//   goes down (camera above the plane); 0 (a hole) above the horizon.
// - insert_into_photo(): the photo's LDR [3, H, W] is linearised (LDR^2.2: exposure-normalised
//   radiance, configs/README.md "Units"), the object is placed at `pose` (WORLD frame of the
//   photo's camera), re-expressed in the lighting's canonical frame, and rendered with
//   importance sampling. Throws sl::Error when the depth does not match the image, when the
//   position is behind the camera, outside the image, or not on the ground (no depth there,
//   or the surface the depth map shows there is more than max_ground_offset_m from y = 0).
// - Outputs are LDR composites clip(c^(1/2.2), 0, 1), the object mask and the shadow map
//   (mean over channels), the 3D box in the photo camera's frame and the 2D box of the mask,
//   and for KITTI labels the fraction of the object hidden by the photo (1 − Σ mask / Σ
//   silhouette) and its truncation (the part of its projected 3D box's 2D extent outside the
//   image).
#pragma once
#include <array>
#include <string>

#include "autodiff/tensor.h"
#include "data/object_placement.h"
#include "render/camera.h"
#include "render/mesh.h"
#include "render/object_insertion.h"
#include "train/inference.h"
#include "train/object_labels.h"

namespace sl::train {

Tensor ground_plane_depth(const render::Camera& camera);

struct PhotoInsertionOptions {
  // Eq. 2's N: 16 light samples per primary sample (64 per fully covered pixel), then on average
  // 2 more where the neighbours were noisy, and the residual filter (radius 2); see the end.
  // Eq. 4: 256 shadow rays per shadow-map texel. (N = 6 and 128 shadow rays until 2026-11-27:
  // see exact_light_rays below; N = 8 until 2026-11-27: see stratify_per_pixel.)
  int aa_samples = 4, light_samples = 16;
  int shadow_width = 160, shadow_height = 90, shadow_rays = 256;
  double ambient = 0.1;
  render::RadianceQueryOptions volume_query{.samples = 32};  // Eq. 1: K, spacing, lookup (the model's)
  double max_ground_offset_m = 1.0;
  uint64_t seed = 0;
  bool radiance_cache = true;  // render/object_insertion.h: probes instead of per-ray volume marches
  // The radiance cache's probes (render/object_insertion.h): 1 m apart, up to 4×6×4 over the
  // object (a 2.6 m truck gets 4 levels) and 4×2×4 for the shadow rays, 24×48 directions; Eq. 2's
  // diffuse control variate on (its normal grid 64×128: 32×64 raised the object's error, 16×32
  // doubled it). KITTI 000008 under the released model's lighting, against a 4096-spp
  // exact-query reference (streetlight-bench insert --size kitti --lighting released, rows
  // production, no_control_variate, cv_normals16/32, cache_4x3x4_1m, shadow128_grid*; 2026-11-23):
  // 0.91% (object 0.79%), was 2.02% (object 1.85%) at the defaults of 2026-11-23. Those figures are
  // the lighting of a release of 2026-11-26; with a later one of that day the same row is 1.65% (object
  // 1.24%, shadow 1.05%; README, Intel Xeon rows of 2026-11-26). Probes 0.5 m apart
  // (up to 4×6×4) gave 0.94% in ~90 ms more; an 8×2×8 shadow grid lowers the shadow term
  // (nuScenes size 0.44% → 0.17%) for 130-160 ms more on KITTI.
  // The shadow rays' grid: up to 8×2×8 probes with 12×24 directions each (the same number of
  // volume marches as 4×2×4 × 24×48): the nuScenes-size shadow term 0.44% → 0.15-0.17%, KITTI's
  // 0.41% → 0.38% (rows shadow_grid8x2x8_dirs*).
  double cache_spacing_m = 1.0;
  int cache_max_y = 6, cache_shadow_max_xz = 8, cache_height = 24, cache_shadow_height = 12;
  bool diffuse_control_variate = true;
  // render/object_insertion.h, "Adaptive sampling" and "Denoising". Under the released model's
  // lighting, against 4096-spp exact-query references (streetlight-bench insert --size
  // kitti|nuscenes --lighting released, rows production, adaptive_off, light16_plain,
  // light16_denoise, adaptive_light*; 2026-11-23, one slow stretch of this VM): N = 16 alone
  // (the former default) 1.22% at nuScenes size; N = 16 filtered 0.83%; N = 8 filtered 0.95%;
  // N = 8 + 2 adaptive, filtered, 0.79% (KITTI 0.77%); N = 6 + 2: 0.84% (KITTI 0.78%) in about
  // 0.86× the time of 8 + 2.
  double adaptive_light_samples = 2;
  int denoise_radius = 2;
  // One stratified set per primary sample, not one per pixel interleaved over its primary
  // samples (2026-11-27): both are unbiased, but under release 0.6.0 (a strong sun near
  // the zenith) the per-pixel sets left twice the variance. KITTI 000008, 16384-spp reference,
  // Intel Xeon (streetlight-bench insert --size kitti --lighting released --bias-runs 8): object
  // noise 0.91% → 0.54% at N = 8 (0.42% at N = 16); total 1.32% → 1.02% (N = 16: 0.92%, +7%
  // time). Under the random stress lighting, 0.98% either way. Without the control variate the
  // per-pixel sets are the better ones (N = 32: object noise 2.27% against 2.46%); with it each
  // primary sample integrates its own residual over a quarter of the pixel's set.
  bool bilinear_env_sampling = true, stratify_per_pixel = false;  // render/object_insertion.h
  // The radiance cache's exact corrections (render/object_insertion.h, "Exact corrections"): 2
  // of each object sample's light rays and 16 of each texel's shadow rays also marched exactly,
  // filtered over 13×13 pixels and 5×5 texels. KITTI 000008 under the released model's lighting,
  // against a 16384-spp exact-query reference (streetlight-bench insert --size kitti --lighting
  // released --reference-spp 16384; Intel Xeon, 2026-11-27): 1.62% (object 1.21%, shadow 1.06%)
  // at the former settings (N = 6, 128 shadow rays, no corrections), 0.93% (object 0.71%, shadow
  // 0.58%) with these, for 0.57 → 1.26 s of insertion on 2 threads. Rows exact_*.
  int exact_light_rays = 2, exact_light_radius = 6;
  int shadow_exact_rays = 16, shadow_exact_radius = 2;
};

// The settings before the exact corrections (N = 6, 128 shadow rays, none marched exactly): about
// half the insertion time at the cache's bias. KITTI 000008 under the released model's lighting
// (streetlight-bench insert, row former_production; Intel Xeon, 2026-11-27): 1.62% against the
// 16384-spp reference in 0.56 s of insertion, against 0.93% in 1.28 s for the defaults.
// streetlight-insert --fast.
PhotoInsertionOptions fast_insertion_options();

// The renderer's options for a photo insertion (importance sampling, the inference path).
render::InsertionOptions insertion_options(const PhotoInsertionOptions& options);

struct PhotoInsertion {
  Tensor composite_ldr;     // [3, H, W]
  Tensor composite_linear;  // [3, H, W] exposure-normalised radiance
  Tensor object_mask;       // [1, H, W]
  Tensor shadow_map;        // [1, H, W] (1 = unshadowed)
  Tensor object_depth;      // [1, H, W] camera-z depth of the object's visible pixels (0 elsewhere)
  bool visible = false;
  double hidden_fraction = 0.0;  // of the object's silhouette, hidden by the photo's nearer surfaces
  double truncated = 0.0;        // KITTI truncation: fraction of the projected 3D box outside the image
  std::array<double, 4> box2d{};
  std::array<double, 7> box3d{};
  double ground_y_m = 0.0;  // where the object's base was set
  double render_ms = 0.0;
};

// The renderer's inputs of that insertion, with the checks above (throws as insert_into_photo):
// the linearised photo, its depth, the camera in the lighting's canonical frame, the lighting's
// env, vsg and grid, and the object placed on the ground. insert_into_photo() renders exactly
// these; test-time refinement (train/lighting_refinement.h) swaps in env/vsg that carry a tape.
render::InsertionInputs photo_insertion_inputs(const EstimatedLighting& lighting, const Tensor& ldr,
                                               const Tensor& depth, const render::Camera& world_camera,
                                               const render::Mesh& object_frame_mesh, const render::Placement& pose,
                                               const PhotoInsertionOptions& options);

PhotoInsertion insert_into_photo(const EstimatedLighting& lighting, const Tensor& ldr, const Tensor& depth,
                                 const render::Camera& world_camera, const render::Mesh& object_frame_mesh,
                                 const render::Placement& pose, const PhotoInsertionOptions& options);

}  // namespace sl::train
