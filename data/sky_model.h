// Physically based clear-sky panoramas: Preetham, Shirley & Smits 1999, "A Practical Analytic
// Model for Daylight" (the Perez distribution with their turbidity fits), plus a solar disk and
// optional procedural clouds. Used to synthesise HDR skies for the sky autoencoder (Sec 3.1)
// and for analytic renderer tests.
//
// Units: radiance is luminance-scaled linear sRGB in kcd/m² — the units of Preetham's zenith
// luminance — so a clear zenith is ~2-30 and the sun's disk ~10^4-10^6.
//
// Sky (above the horizon): Y, x, y each follow  value = zenith · F(θ, γ) / F(0, θs)  with
// F(θ, γ) = (1 + A·e^{B / cos θ})(1 + C·e^{D γ} + E·cos² γ), θ the view's zenith angle, γ its
// angle to the sun, θs the sun's zenith angle; xyY → XYZ → linear sRGB (D65, IEC 61966-2-1).
// Sun: a disk of angular radius 0.265° whose radiance is the extraterrestrial solar luminance
// (1.9·10^6 kcd/m² = 128 klx over the disk's solid angle) times a per-channel transmittance
// exp(−m·(0.008735·λ^−4.08 + β·λ^−1.3)) (Rayleigh and Ångström aerosol terms of Preetham's
// appendix, β = 0.04608·T − 0.04586, λ in µm at 0.61/0.55/0.465 for R/G/B, m the Kasten-Young
// relative air mass). At turbidity 3 the disk is 4·10^4 (sun at 5° or 90°) to 2·10^5 (15-45°)
// times the zenith luminance, as for the real sun (~1.6·10^9 vs ~10^4 cd/m²), and a low sun
// is dimmer and redder. The disk is splatted with 256 stratified samples so its
// solid-angle-weighted energy L_sun·Ω_sun is exact at any resolution.
// Ground (below the horizon): Lambertian, albedo · E / π with E the horizontal irradiance of the
// sky and sun (numerically integrated).
// Clouds (optional): seeded value-noise fBm on a plane above the camera; cover c ∈ [0, 1] blends
// the sky towards a grey cloud radiance and multiplies the sun by exp(−4c).
//
// Requires: sun elevation in [0, π/2], turbidity in [1.7, 10], albedo in [0, 1],
//   cloud_cover in [0, 1]. Throws sl::Error naming the parameter and value otherwise.
// Guarantees: finite, non-negative radiance everywhere; render() is deterministic for a given
//   SkyParams (clouds depend only on cloud_seed), with any number of threads.
#pragma once
#include <cstdint>

#include <glm/glm.hpp>

#include "autodiff/tensor.h"

namespace sl::data {

struct SkyParams {
  double sun_elevation_rad = 0.7853981633974483;  // 45°
  double sun_azimuth_rad = 0.0;                   // render/equirect.h azimuth
  double turbidity = 3.0;
  double ground_albedo = 0.2;
  bool sun_disk = true;
  double cloud_cover = 0.0;
  uint64_t cloud_seed = 0;
};

class PreethamSky {
 public:
  explicit PreethamSky(const SkyParams& params);

  const SkyParams& params() const { return p_; }
  glm::dvec3 sun_direction() const { return sun_dir_; }
  // Clear-sky radiance (no disk, no clouds) for a direction with y ≥ 0 (clamped at the horizon).
  glm::dvec3 clear_sky_radiance(const glm::dvec3& direction) const;
  // Sky with clouds (no disk) above the horizon, ground below it.
  glm::dvec3 radiance(const glm::dvec3& direction) const;
  glm::dvec3 sun_radiance() const { return sun_rgb_; }  // disk radiance, after clouds
  double sun_solid_angle() const;
  double zenith_luminance() const { return zenith_Y_; }
  // Cloud cover in [0, 1] seen in `direction` (0 without clouds or below the horizon).
  double cloud_cover_at(const glm::dvec3& direction) const;

  // HDR panorama [3, height, width] (render/equirect.h layout).
  Tensor render(int height, int width) const;

 private:
  SkyParams p_;
  glm::dvec3 sun_dir_;
  double theta_s_ = 0.0;
  double coef_Y_[5], coef_x_[5], coef_y_[5];
  double zenith_Y_ = 0.0, zenith_x_ = 0.0, zenith_y_ = 0.0;
  double norm_Y_ = 1.0, norm_x_ = 1.0, norm_y_ = 1.0;  // F(0, θs)
  glm::dvec3 sun_rgb_{0.0};
  glm::dvec3 ground_rgb_{0.0};
};

// Seeded random sky parameters (util/random.h): elevation uniform in [0°, 85°], azimuth in
// [−π, π), turbidity in [2, 8], albedo in [0.05, 0.4], clouds in half of the samples with cover
// in [0.1, 0.7]. Sample `index` of `seed` is the same on every machine and thread count.
SkyParams sample_sky_params(uint64_t seed, uint64_t index);

}  // namespace sl::data
