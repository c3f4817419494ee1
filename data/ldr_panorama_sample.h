// Real LDR panoramas (../shared/data/pano_ldr: 8-bit sRGB-encoded street panoramas whose sun is
// hand-labelled, data/sun_labels.h) as street samples for stages 2 and 3 (Sec 3.4, the paper's
// HoliCity branch) and for the real-sky benchmark (train/real_sky_benchmark.h).
//
// Units. A panorama's values are its 8-bit codes / 255, read as the paper's LDR
// clip(L^(1/2.2), 0, 1) at the exposure its camera chose, so exposure = 1 and the
// relative linear radiance is codes^2.2 (clipped where the camera clipped). This is how the
// estimator reads a photo (train/inference.h), so training and use see the same input.
//
// Sample (seed, stream) of a panorama, a pure function of both (draw_panorama_sample,
// data/panorama_sample.h, so an LDR and an HDR panorama of one width get the same draws):
//   - azimuth rotation by the draw's whole number of columns (exact) and, with options.flip, a
//     horizontal flip (directions (x, y, z) → (−x, y, z)); the labelled sun turns with it;
//   - white balance and exposure jitter applied to the linear radiance,
//       L = codes^2.2 · g_c / grey(g) · k,
//     except that a texel the camera clipped (any channel ≥ 254/255) stays at L = 1 in every
//     channel: a clipped sun must not turn into a grey, unclipped disk when the jitter darkens it;
//   - every resampling is of L, as a sensor integrates radiance, and LDR is to_ldr(·, 1) of the
//     result: the view is a perspective crop of L (random_perspective_crop with the draw's
//     stream) from a camera at (0, camera_height_m, 0); pano_hdr and sky_hdr are L area-resized
//     to pano_width × pano_height, pano_ldr their LDR. So an oracle that returns L has zero
//     LDR radiance loss along the crop's rays and the sphere's (tests/train);
//   - the sky mask (the LDR sky L1's and the rays' sky flag): estimate_sky_mask (data/panorama.h:
//     above the horizon, and bright or blue relative to the upper hemisphere's median luminance)
//     on the linear radiance of the UNJITTERED panorama, computed once (LdrPanorama) and turned
//     with the image; a texel is sky when at least half of it is, after area resizing;
//   - depth unknown (0: a hole), so no depth loss and an empty unprojected volume;
//   - sun_direction from the label, sun_known when the label has a position (visible, or
//     occluded with the place the shadows give).
// The teacher's intensity and latent pseudo-labels come from the stage-1 encoder run on
// pano_ldr by the lighting stage, as for every sample (train/lighting_stage.h).
// With options.flip = false and no jitter it is the real-sky benchmark's crop.
// Throws: sl::Error naming `id` for a panorama that is not [3, H, 2H].
#pragma once
#include <cstdint>
#include <string>

#include <glm/glm.hpp>

#include "autodiff/tensor.h"
#include "data/panorama_sample.h"
#include "data/street_dataset.h"

namespace sl::data {

struct LdrPanorama {
  Tensor ldr;       // [3, H, 2H] codes / 255 (the working resolution)
  Tensor sky_mask;  // [1, H, 2H] 0/1, or undefined (not needed: the benchmark)
  // ldr_linear(ldr), kept so that each sample scales it instead of raising every code to 2.2
  // again (the same bits); undefined: computed per sample.
  Tensor linear;
  bool sun_known = false;
  double sun_weight = 1.0;  // StreetSample::sun_weight of its samples
  glm::dvec3 sun_direction{0.0, 1.0, 0.0};  // world, unrotated panorama
};

// The linear radiance codes^2.2 of an LDR panorama [3, H, 2H], 1 where the camera clipped.
Tensor ldr_linear(const Tensor& ldr);

// The sky mask rule above, on an LDR panorama [3, H, 2H].
Tensor ldr_sky_mask(const Tensor& ldr);

StreetSample ldr_panorama_street_sample(const LdrPanorama& pano, const std::string& id, uint64_t seed, uint64_t stream,
                                        const PanoramaSampleOptions& options = {}, bool keep_images = true);

}  // namespace sl::data
