// Operations on full-sphere equirectangular panoramas (docs/DESIGN.md, "Panoramas").
//
// A panorama is an F32 tensor [C, H, W] covering the whole sphere: rows span elevation +90°
// (row 0) to −90°, columns span azimuth −180° to +180°. Direction ↔ pixel goes only through
// render/equirect.h. W = 2H is the usual shape but not required.
//
// Guarantees:
// - rotate_azimuth is exact (a column roll) when the shift is a whole number of pixels, and
//   linear along rows with wrap otherwise; content at azimuth φ moves to φ + delta.
// - resize_area is an exact area average in solid angle: Σ L·Ω of every channel is preserved
//   (to float rounding) for any output size, so a one-texel sun is spread, never dropped.
// - crop_perspective samples bilinearly with azimuth wrap and returns the crop's camera
//   (render/camera.h; centre at the origin) so pixels and world directions stay consistent.
// - to_ldr is the paper's LDR (Sec 3.4): clip((exposure·L)^(1/2.2), 0, 1); NaN → 0.
// - estimate_sky_mask: a documented heuristic (see SkyMaskParams) for panoramas without a mask.
// Throws sl::Error naming the function and the offending shape or value.
#pragma once
#include <glm/glm.hpp>

#include "autodiff/tensor.h"
#include "render/camera.h"
#include "render/exposure.h"  // median_luminance, exposure_for_ldr_median
#include "util/math.h"  // luminance

namespace sl::data {

// Checks an F32 [C, H, W] panorama with C ≥ 1, H ≥ 1, W ≥ 1.
void check_panorama(const Tensor& pano, const char* op);

Tensor rotate_azimuth(const Tensor& pano, double delta_rad);
// The direction that content at `d` moves to under rotate_azimuth(·, delta_rad).
glm::dvec3 rotate_direction_azimuth(const glm::dvec3& d, double delta_rad);

// Solid-angle-weighted area resampling to [C, out_height, out_width].
Tensor resize_area(const Tensor& pano, int out_height, int out_width);

// Σ over texels of L·Ω for one channel (units of L times steradians).
double radiant_power(const Tensor& pano, int channel);

// Bilinear sample at continuous panorama coordinates (u, v); u wraps, v clamps to the poles'
// texel centres. Writes C values to out.
void sample_bilinear(const float* pano, int channels, int height, int width, double u, double v,
                     float* out);

struct PerspectiveCropParams {
  double horizontal_fov_rad = 1.0471975511965976;  // 60°
  double yaw_rad = 0.0, pitch_rad = 0.0, roll_rad = 0.0;
  int width = 256, height = 128;
};
struct PerspectiveCrop {
  Tensor image;   // [C, height, width]
  render::Camera camera;  // intrinsics from the fov, pose from yaw/pitch/roll, centre at the origin
};
PerspectiveCrop crop_perspective(const Tensor& pano, const PerspectiveCropParams& params);

Tensor to_ldr(const Tensor& hdr, double exposure);

// Heuristic sky mask [1, H, W] (1 = sky) for RGB HDR panoramas. A texel is sky when its centre
// lies above the horizon and it is bright or blue relative to the upper hemisphere:
//   luminance ≥ bright_ratio · m, or (blue share B/(R+G+B) ≥ blue_share and
//   luminance ≥ blue_min_ratio · m), where m is the median luminance above the horizon.
// Sky is the brightest large region of a daytime street panorama and clear sky is blue; walls
// and trees are darker and greyer or greener. It fails for night panoramas and white facades.
struct SkyMaskParams {
  double bright_ratio = 1.0;
  double blue_share = 0.36;
  double blue_min_ratio = 0.25;
};
Tensor estimate_sky_mask(const Tensor& pano, const SkyMaskParams& params = {});

// A resampled mask back to {0, 1}: 1 where the value is ≥ 0.5, else 0. Works in place on a
// contiguous F32 tensor (a fresh resample) and returns it.
Tensor binarize_mask(Tensor mask);

}  // namespace sl::data
