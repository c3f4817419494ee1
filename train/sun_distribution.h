// A probability over sun directions on the upper hemisphere, in place of one averaged direction
// (issue 53). A network trained to regress one direction with an angular L1 loss pays to put a
// sun whose azimuth it cannot tell near the zenith, the direction nearest on average to every
// azimuth, and every shadow it casts is then short. A distribution can keep two guesses apart
// (in front of the camera, or behind it) and its answer is read at the MODE, not the mean.
//
// The grid: `elevation_bins` rings × `azimuth_bins` sectors over elevations [0°, 90°] of the
// canonical frame (train/street_batch.h: the camera looks at azimuth 0, −Z). The rings are equal
// in sin(elevation), so every cell has the same solid angle 2π / K (K = rings × sectors): a
// cell's probability is a density up to one constant, and the mode of the cells is the mode of
// the density. Cell k = ring · azimuth_bins + sector; ring 0 touches the horizon; sector j
// spans azimuths [−π + j·2π/A, −π + (j+1)·2π/A) (render/equirect.h: azimuth φ = atan2(x, −z)).
//
// Contract:
// - cell_directions(grid) → [K, 3] unit cell centres (sector centre azimuth, ring centre in
//   sin(elevation)).
// - soft_target(grid, sun) → [K] probabilities ∝ exp(κ(d_k·s − 1)), κ from width_deg (the
//   lobe's standard deviation in degrees: κ = 1/σ²). A sun below the horizon is lifted to it
//   (no cell lies below); a zero vector throws.
// - sun_distribution_loss(logits [N, K], targets [N, K], weights [N]) → scalar
//   Σ_i w_i · CE(t_i, softmax(logits_i)) / N, the cross-entropy −Σ_k t_k log p_k computed as
//   logsumexp(logits) − Σ_k t_k logits_k (stable for any finite logits; differentiable in
//   logits).
// - sun_half_loss(grid, logits [N, K], targets [N, K], weights [N]) → scalar: the same
//   cross-entropy on the distribution's two halves, in front of the camera (cells whose sector
//   centre has |azimuth| < 90°) and behind it: Σ_i w_i · CE((y_i, 1 − y_i), (p_i, 1 − p_i)) / N,
//   y_i = Σ_front t_ik and log p_i = logsumexp over the front cells of the logits − logsumexp
//   over all. It weighs the coarse front/back decision apart from where within a half the sun
//   lies (issue 53: front and back were confused). Needs azimuth_bins divisible by 4, so that no
//   sector straddles the boundary. Finite for any finite logits; differentiable in logits.
// - mirror_cells(grid, p) → p of the mirrored image: azimuth φ → −φ maps sector j to A − 1 − j.
// - read_sun_distribution(grid, p, radius_deg) → a direction whose AZIMUTH is the mode cell's,
//   refined locally to the probability-weighted mean direction of the cells within radius_deg of
//   the mode cell's centre, and whose ELEVATION is the median, in degrees, of the elevation
//   distribution of the sectors within radius_deg of that azimuth (linear within a ring): the
//   densest cell reads too high when the elevation is uncertain, because the equal-area rings span
//   more degrees the higher they lie. Its confidence: the probability within radius_deg of the
//   mode cell's centre (in [0, 1]; 1 = certain). With two peaks at separated azimuths it answers
//   at the larger one, never between them.
//   Throws for a p that is not K finite non-negative values with a positive sum.
// - weigh_by_azimuth(grid, p, q, weight) → p reweighed by a second opinion on the azimuth alone
//   (the learned glare detector's azimuth head, train/sun_glare.h): p'_k ∝ p_k · q_s(k)^weight,
//   s(k) the sector of q (A' sectors over the same azimuth range) holding cell k's sector centre,
//   normalised to sum 1. weight 0 returns p unchanged (the same values); a q of all equal values
//   also leaves p as it is (up to rounding). q values are floored at 1e-6 so that no cell is ruled
//   out. Throws for a p that read_sun_distribution would refuse, an empty q, a negative or
//   non-finite q value, or a weight that is negative or not finite.
// - weigh_by_cells(grid, p, f, weight) → p'_k ∝ p_k · f_k^weight, normalised: p reweighed by a
//   second opinion given per cell, as a likelihood ratio (the learned glare detector's map,
//   train/sun_glare.h glare_sky_factor). Same rules as weigh_by_azimuth: weight 0 returns p
//   unchanged; equal factors leave p as it is (up to rounding); factors are floored at 1e-6; throws
//   for a bad p, a weight that is negative or not finite, or f not K finite values >= 0.
// - cell_of_direction(grid, d) → the cell holding direction d (any length > 0), or −1 below the
//   horizon (d.y < 0). Throws for a zero or non-finite d.
// - low_sun_weight(sun, boost, below_deg) → a label's weight factor 1 + boost · clamp((below − e)
//   / below, 0, 1), e = the sun's elevation in degrees (below the horizon counts as 0): 1 at and
//   above `below_deg`, 1 + boost at the horizon, linear between. The labelled training suns sit
//   higher than the test splits' (LDR train: median 44°, 11% below 30°; test: 35.5°, 39%), so a
//   network that cannot tell the elevation falls back on a prior that is too high; this weighs
//   the rarer low suns up. boost ≥ 0 and below_deg in (0, 90] (else throws); a zero vector throws.
#pragma once
#include <cstdint>
#include <vector>

#include <glm/glm.hpp>

#include "autodiff/tensor.h"

namespace sl::train {

struct SunGrid {
  int64_t elevation_bins = 0, azimuth_bins = 0;
  bool enabled() const { return elevation_bins > 0 && azimuth_bins > 0; }
  int64_t cells() const { return elevation_bins * azimuth_bins; }
};

void validate(const SunGrid& grid);

Tensor cell_directions(const SunGrid& grid, DType dtype = DType::F32);

std::vector<double> soft_target(const SunGrid& grid, const glm::dvec3& sun, double width_deg);

Tensor sun_distribution_loss(const Tensor& logits, const Tensor& targets, const Tensor& weights);

Tensor sun_half_loss(const SunGrid& grid, const Tensor& logits, const Tensor& targets, const Tensor& weights);

std::vector<double> mirror_cells(const SunGrid& grid, const std::vector<double>& p);

// softmax of one row of logits, in double.
std::vector<double> softmax_row(const std::vector<double>& logits);

struct SunReadout {
  glm::dvec3 direction{0.0, 1.0, 0.0};
  int64_t mode_cell = 0;
  double confidence = 0.0;  // probability within the readout radius of the mode
};

SunReadout read_sun_distribution(const SunGrid& grid, const std::vector<double>& p, double radius_deg = 20.0);

std::vector<double> weigh_by_azimuth(const SunGrid& grid, const std::vector<double>& p, const std::vector<double>& q,
                                     double weight);

std::vector<double> weigh_by_cells(const SunGrid& grid, const std::vector<double>& p, const std::vector<double>& f,
                                   double weight);

int64_t cell_of_direction(const SunGrid& grid, const glm::dvec3& d);

double low_sun_weight(const glm::dvec3& sun, double boost, double below_deg);

}  // namespace sl::train
