// Sun (peak) extraction from an HDR panorama: the ground truth f_dir and f_intensity of the sky
// vector (paper Sec 3.1, "Sky Modeling Supervision").
//
// Method: luminance (Rec. 709) is box-blurred over 3×3 texels (azimuth wraps) so that a single
// noisy texel cannot win; the blurred maximum seeds the peak. Texels within region_radius of the
// seed whose luminance exceeds threshold_fraction × the region's peak form the sun; its
// direction is the (L − threshold)·Ω-weighted mean of the texels' unit direction vectors,
// normalised. Averaging vectors, not pixel coordinates, handles the azimuth seam and the zenith
// (where a disk spans every column of the top rows).
//
// Requires: an F32 RGB panorama [3, H, W] (render/equirect.h layout). NaN, Inf and negative
//   texels are treated as 0.
// Guarantees: direction is a unit world vector; for a panorama without any positive texel,
//   found = false, direction = the +Y zenith and intensities are 0.
// Throws: sl::Error naming the shape or parameter when the input is not an RGB panorama or the
//   parameters are out of range.
#pragma once
#include <glm/glm.hpp>

#include "autodiff/tensor.h"

namespace sl::data {

struct SunExtractionParams {
  double threshold_fraction = 0.5;  // of the region's peak luminance, in (0, 1)
  // Search radius around the seed; 0 picks max(3°, 4 texel heights).
  double region_radius_rad = 0.0;
};

struct SunEstimate {
  bool found = false;
  glm::dvec3 direction{0.0, 1.0, 0.0};  // unit, world frame
  double elevation_rad = 0.0, azimuth_rad = 0.0;
  // Solid-angle-weighted mean RGB radiance of the sun texels (the HDR peak intensity).
  glm::dvec3 radiance_rgb{0.0};
  // Σ L·Ω over the sun texels: the sun's contribution to irradiance at normal incidence,
  // independent of the panorama's resolution.
  glm::dvec3 power_rgb{0.0};
  double peak_luminance = 0.0;  // the brightest single texel's luminance in the region
  int texel_count = 0;
};

SunEstimate extract_sun(const Tensor& pano, const SunExtractionParams& params = {});

}  // namespace sl::data
