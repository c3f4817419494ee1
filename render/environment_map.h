// Equirectangular HDR environment maps: lookup, rotation, resizing and importance sampling.
//
// Contract:
// - Radiance is a [3, H, W] F32 (or F64) tensor, linear HDR, laid out by render/equirect.h
//   (row 0 = zenith, u wraps at the azimuth seam). H >= 1, W >= 2; finite, non-negative values
//   (negative or NaN texels throw, naming the texel).
// - lookup(d): bilinear between texel centres, wrapping in azimuth and clamping at the poles.
// - env_lookup(env, dirs) is the same lookup as ONE tape op over a batch of directions,
//   differentiable with respect to the texels (and not the directions). Zero-length or
//   non-finite directions read 0 and pass no gradient.
// - Importance sampling: a texel is chosen with probability ∝ (the average luminance of the
//   bilinear lookup over it: tent weights 9/16, 3/32, 1/64 over its 3×3 neighbourhood) × its
//   solid angle (piecewise constant), then a direction uniformly in solid angle inside it. pdf() is in
//   solid angle (1/sr) and equals the density sample() draws from, Jacobian of the sphere
//   (the cos θ of the elevation) included. A black map falls back to uniform sphere sampling.
// - Bilinear importance sampling (sample_bilinear / pdf_bilinear): the density is
//   proportional to the luminance of the bilinear lookup itself, at full resolution. A cell of
//   the lookup (between four texel centres; half cells at the poles, where rows clamp) is
//   chosen with probability ∝ its integral of luminance × solid angle (at the cell centre),
//   then a point inside it ∝ the bilinear luminance (exact inversion of its marginal and
//   conditional, both linear). So L/pdf is nearly constant inside every cell — a sun spread
//   over a few texels is sampled with almost no variance, where the texel sampler above
//   leaves L/pdf varying up to 64× next to it. pdf_bilinear() is the exact solid-angle density
//   of sample_bilinear() (0 only where the lookup is black, and at the two pole points).
//   Black map: uniform sphere, as above.
// - rotated(φ): the map seen after rotating the world by φ about +Y (azimuth φ → φ + angle).
// - resized(W', H'): area-weighted (solid-angle) averaging, so the integral of radiance over
//   the sphere is preserved; never point-samples a sun.
#pragma once
#include <vector>

#include <glm/glm.hpp>

#include "autodiff/tensor.h"
#include "render/equirect.h"

namespace sl::render {

class EnvironmentMap {
 public:
  EnvironmentMap() = default;
  explicit EnvironmentMap(const Tensor& radiance);

  int width() const { return width_; }
  int height() const { return height_; }
  const Tensor& radiance() const { return radiance_; }  // [3, H, W] f32

  glm::vec3 lookup(const glm::vec3& direction) const;
  // lookup() at unit panorama coordinates (see env_bilinear_taps_unit).
  glm::vec3 lookup_unit(const equirect::UV& unit) const;
  glm::vec3 texel(int row, int col) const;

  struct Sample {
    glm::vec3 direction;  // unit, world
    glm::vec3 radiance;   // lookup(direction)
    float pdf;            // solid-angle density
  };
  Sample sample(float u1, float u2) const;
  float pdf(const glm::vec3& direction) const;
  Sample sample_bilinear(float u1, float u2) const;
  // sample_bilinear(u1, u2).direction alone (no radiance lookup, no density: callers that mix
  // techniques evaluate the mixture's density themselves).
  glm::vec3 sample_bilinear_direction(float u1, float u2) const;
  // The same, also giving the sample's unit panorama coordinates (u/W, v/H), so callers read
  // pdf_bilinear_unit() and lookups without an atan2/asin.
  glm::vec3 sample_bilinear_direction(float u1, float u2, equirect::UV& unit) const;
  float pdf_bilinear(const glm::vec3& direction) const;
  // pdf_bilinear() at unit panorama coordinates (equirect::direction_to_uv(x, y, z, 1, 1));
  // identical bits to pdf_bilinear(d) for the coordinates of d.
  float pdf_bilinear_unit(const equirect::UV& unit) const;
  // The same given the direction's cos(elevation) = √(x² + z²) (no cosine of v; equal to the
  // above up to float rounding).
  float pdf_bilinear_unit(const equirect::UV& unit, double cos_elevation) const;
  // Batches of the two above (render/environment_map_lanes.cpp): for i < n,
  // directions[i] = sample_bilinear_direction(u1[i], u2[i], units[i]), and
  // densities[i] = pdf_bilinear_unit(units[i], cos_elevation[i]) (without cos_elevation when it is
  // null). The same bits as the one-at-a-time forms: their double arithmetic runs in 8 AVX-512
  // lanes where compiled (the inverse CDFs' divisions and square roots, which a scalar draw
  // chains), libm's sines and cosines one by one; groups with unusual input take the scalar path.
  void sample_bilinear_directions(int n, const float* u1, const float* u2, glm::vec3* directions,
                                  equirect::UV* units) const;
  void pdf_bilinear_units(int n, const equirect::UV* units, const double* cos_elevation, float* densities) const;
  // The scalar loops the batches equal (the fallback, and the reference of their tests).
  void sample_bilinear_directions_scalar(int n, const float* u1, const float* u2, glm::vec3* directions,
                                         equirect::UV* units) const;
  void pdf_bilinear_units_scalar(int n, const equirect::UV* units, const double* cos_elevation, float* densities) const;

  // Integral of radiance over the sphere, per channel (W/m²/sr × sr).
  glm::dvec3 integral() const;

  EnvironmentMap rotated(double azimuth_rad) const;
  EnvironmentMap resized(int width, int height) const;

 private:
  void build_sampling();
  void build_bilinear_sampling();

  Tensor radiance_;
  int width_ = 0, height_ = 0;
  std::vector<float> rgb_;         // interleaved H×W×3 copy for fast lookup
  std::vector<double> row_cdf_;    // H+1 entries, marginal over rows
  std::vector<double> col_cdf_;    // H×(W+1), conditional per row
  std::vector<double> texel_pdf_;  // probability of each texel (sums to 1)
  // Bilinear sampling over (H + 1) × W lookup cells: cell row k spans v in [k − ½, k + ½]
  // clamped to [0, H], between texel rows k − 1 and k (clamped); column c spans u in
  // [c + ½, c + 3/2] between texel columns c and c + 1 (wrapping).
  std::vector<float> lum_;           // H×W texel luminance
  std::vector<double> cell_row_cdf_;  // H+2 entries
  std::vector<double> cell_col_cdf_;  // (H+1)×(W+1), conditional per cell row
  std::vector<double> cell_prob_;     // (H+1)×W probability of each cell
  // Guide tables of the two CDFs above: entry i is the cell holding u = i/n (n = cells), where
  // the inversion's search starts, so a draw looks at one or two entries instead of a binary
  // search (the same cell as the search: tested).
  std::vector<int> cell_row_guide_;   // H+1
  std::vector<int> cell_col_guide_;   // (H+1)×W
};

// The four texels and weights of the bilinear lookup in direction (x, y, z) of an H×W map:
// between texel centres, azimuth wrapping, rows clamped at the poles. Shared by every lookup.
struct EnvTaps {
  int64_t index[4];  // row·W + col
  double weight[4];
};
EnvTaps env_bilinear_taps(double x, double y, double z, int width, int height);
// The same from unit panorama coordinates (equirect::direction_to_uv(x, y, z, 1, 1)), so one
// atan2/asin serves maps of several sizes; identical bits to the form above.
EnvTaps env_bilinear_taps_unit(const equirect::UV& unit, int width, int height);

// Differentiable batched lookup (one tape node): env [3, H, W], directions [N, 3] -> [N, 3].
Tensor env_lookup(const Tensor& env, const Tensor& directions);

// Resizes a [3, H, W] panorama tensor preserving the integral over the sphere.
Tensor resize_panorama(const Tensor& panorama, int width, int height);

}  // namespace sl::render
