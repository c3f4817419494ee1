// Real HDR panoramas as training samples for stages 2 and 3 (Sec 3.4, the paper's HoliCity
// branch): one seeded, augmented perspective crop of a panorama, packaged as a StreetSample
// (data/street_dataset.h) so the lighting stage treats it like a generated street.
//
// Augmentation, all a pure function of (seed, stream) (util/random.h):
//   - azimuth rotation by a whole number of columns (exact), always: in many public HDRI sets
//     the sun sits at one column (../shared/data/MANIFEST.md);
//   - a horizontal flip with probability 1/2 (options.flip): pixels mirrored, directions
//     (x, y, z) → (−x, y, z) (data/augment.h flip_panorama);
//   - white balance: per-channel gains 2^u, u uniform in [−white_balance_stops, +...], scaled
//     so the Rec. 709 luminance of grey is unchanged;
//   - a perspective crop with field of view, yaw, pitch and roll drawn from options.crop, from
//     a camera at (0, camera_height_m, 0) (the panorama's centre);
//   - exposure: the crop's median luminance maps to the LDR value ldr_median (as the street
//     generator does for its views), times 2^s, s uniform in [−exposure_stops, exposure_stops].
//
// Labels:
//   - sun_direction from peak extraction (data/sun_extraction.h) on the augmented panorama;
//     sun_known only when the sun is HARD: sun_share ≥ hard_sun_share, where sun_share is the
//     fraction of the panorama's Σ L·Ω (luminance, whole sphere) within hard_sun_radius_deg of
//     the extracted direction, and the sun is above the horizon. A clear sun holds 0.3-0.95 of
//     the light; overcast, hazy, night and indoor panoramas hold < 0.2 (MANIFEST's "sun5").
//   - the sky mask: estimate_sky_mask (data/panorama.h: bright or blue relative to the upper
//     hemisphere's median, above the horizon only) on the full-resolution panorama, then
//     area-resized (a texel is sky when at least half of it is) and cropped with the view.
//   - depth: unknown. The view's depth is 0 everywhere (a hole), so no depth loss applies and
//     the unprojected RGBα volume is empty; the rays of the radiance-consistency loss start at
//     the panorama's centre, which is the camera centre.
// Requires: an RGB panorama [3, H, W] with W = 2H (throws naming `id` otherwise).
// Guarantees: finite outputs (NaN, Inf and negative texels of real files are zeroed first).
#pragma once
#include <cstdint>
#include <string>

#include "autodiff/tensor.h"
#include "data/augment.h"
#include "data/street_dataset.h"
#include "data/sun_extraction.h"

namespace sl::data {

struct PanoramaSampleOptions {
  CropRanges crop{};                         // view size, fov / pitch / roll ranges
  int pano_width = 256, pano_height = 128;   // size of the sample's pano_hdr / pano_ldr / mask
  double camera_height_m = 1.6;
  double ldr_median = 0.4;
  double exposure_stops = 0.5;
  double white_balance_stops = 0.15;
  bool flip = true;
  bool rotate = true;                        // false only for tests
  double hard_sun_share = 0.25;
  double hard_sun_radius_deg = 5.0;
  double low_label_weight = 1.0;             // LDR panoramas: sun_weight of a low-confidence label
  double tone_stops = 0.0;                   // input tone curve: gamma 2^u, u uniform in ±tone_stops
};

struct SunHardness {
  SunEstimate sun;
  double share = 0.0;  // fraction of the sphere's Σ L·Ω within the radius of sun.direction
  bool hard = false;   // share ≥ min_share and the sun is above the horizon
};
SunHardness sun_hardness(const Tensor& pano, double radius_deg = 5.0, double min_share = 0.25);

// Σ L·Ω per channel over the texels of an RGB equirectangular map [3, H, W] (a panorama, W = 2H,
// or the generator's sky dome, W = 4H; render/equirect.h) whose centre lies within
// radius_deg of the unit direction `sun` (Ω of a texel: (2π/W)(π/H)·cos(elevation)): the sun's
// energy, the label of the sky vector's intensity where the sky is HDR (train/lighting_stage.h).
glm::dvec3 sun_energy_rgb(const Tensor& pano, const glm::dvec3& sun, double radius_deg = 5.0);

// Replaces NaN, Inf and negative texels by 0 and checks the shape (W = 2H, 3 channels);
// `name` is used in errors.
Tensor sanitized_panorama(const Tensor& pano, const std::string& name);

// The random draws of sample (seed, stream) of a panorama `width` columns wide, in the order
// panorama_street_sample makes them (every one unconditionally, so each choice is independent of
// the others' flags): the azimuth shift in whole columns (0 when !options.rotate), the flip, the
// white-balance gains, the exposure jitter and the stream of the crop camera
// (random_perspective_crop). The real-sky benchmark's LDR panoramas take their crops from it too
// (train/real_sky_benchmark.h), so an LDR and an HDR panorama of one width get the same crops.
struct PanoramaSampleDraw {
  int64_t shift_columns = 0;
  bool flip = false;
  double gain[3] = {1.0, 1.0, 1.0};
  double exposure_jitter = 1.0;
  uint64_t crop_stream = 0;
  double tone_gamma = 1.0;  // drawn after everything else, so draws without it are unchanged
};
PanoramaSampleDraw draw_panorama_sample(uint64_t seed, uint64_t stream, int64_t width,
                                        const PanoramaSampleOptions& options = {});

StreetSample panorama_street_sample(const Tensor& pano_hdr, const std::string& id, uint64_t seed, uint64_t stream,
                                    const PanoramaSampleOptions& options = {});

}  // namespace sl::data
