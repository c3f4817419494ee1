// The sun's direction read from a photograph's own cast shadows, given its depth map: a
// classical cue beside the network's sky head, for photos with real geometry (lidar, a depth
// file, a generated street). Without geometry that can cast a shadow (the ground plane alone)
// it finds nothing, and the caller keeps the network's sun.
//
// Method (documented choice):
// - Ground samples: every stride-th pixel with a valid depth within max_distance_m whose point
//   lies within ground_tolerance_m of the ground. The ground is the RANSAC plane of
//   data/kitti.h fitted to the points (the median height of the low points when no plane is
//   found), so a camera pitched against the road does not tilt it. Only FREE-SPACE ground
//   counts: each column is walked from the image's bottom up and stops at the first surface
//   that is not ground (lidar sees the road through a car's windows; those pixels show the car).
//   Samples under cover (the march straight up is blocked within cover_m: the ground under a
//   car, a balcony, a canopy) are dropped too: they are dark for almost every sun.
// - Brightness: x = log of the linear luminance (LDR^2.2, Rec. 709 weights). Ground more than
//   level_split_m above the road (sidewalks, curbs) is its own level and material, so each
//   sample is measured against its level's 75th percentile (the lit ground when at least a
//   quarter of the level is lit): xr = x − x_75; the sample is DARK when xr < −dark_log.
// - Shadow test for a sun direction s (world, unit): from the sample lifted 2 cm above the
//   ground, march along s at geometrically spaced distances (march_steps from 0.1 m to
//   march_m); a step whose projection lands on a valid depth d with d + eps < z < d + thickness_m
//   (z the step's camera depth, eps = 2% of d, at least 5 cm) is blocked. Steps that leave the
//   image, pass behind the camera or land on a hole end the march unblocked: the test can only
//   see what the depth map shows.
// - Score of s: F_beta of the blocked samples against the dark ones (precision = the blocked
//   share that is dark, recall = the dark share that is blocked). beta < 1 weighs precision: a
//   blocked sample that is bright contradicts s, while a dark sample the depth map cannot
//   explain may be the shadow of something outside the view. Directions that block fewer than
//   min_shadow_samples samples score 0.
// - Search: a coarse grid over azimuth × elevation (coarse_step_deg, elevations in
//   [min_elevation_deg, max_elevation_deg]); then, around each of the best `refine_seeds`
//   coarse directions, a fine grid of ±coarse_step_deg at fine_step_deg. The best fine
//   direction wins; ties keep the first in grid order, so the result is deterministic.
// - found = (best score ≥ min_score) and the winner is above the lowest elevation searched: a
//   winner there wants an ever lower sun, i.e. its shadows come from casters whose tops are out
//   of view, whose height (and so the sun's elevation) the depth cannot tell. Elevations start at
//   15° (daylight street photos). On the 166 generated test streets of the Table 1 run, this
//   rule and the 15° floor took the confident fits from 102 at a median error of 46° to 68 at
//   34° (streetlight-bench sun-from-shadows).
// - shadow_ratio = exp(median xr over the blocked dark samples − median xr over the lit
//   samples) at the winner: how much darker the photo's shadowed ground is than its lit ground,
//   which sets the sun's strength against the sky. Blocked samples that are not dark are left
//   out: they include the fit's own misses, which would pull the ratio toward 1.
//
// Requires: ldr F32 [3, H, W] in [0, 1]; depth F32 [H, W] or [1, H, W] (camera z, metres; 0,
//   negative, NaN or Inf are holes); the camera's intrinsics of size W×H (world +Y up).
// Guarantees: deterministic for any thread count; direction is a unit world vector with
//   elevation in [min_elevation_deg, max_elevation_deg]; nothing non-finite reaches the result
//   (a non-finite pixel value is skipped as a sample). With found = false the direction is the
//   best guess and must not be used as the sun.
// Throws: sl::Error naming the shape or option that is out of range.
#pragma once
#include <array>
#include <vector>

#include <glm/glm.hpp>

#include "autodiff/tensor.h"
#include "render/camera.h"

namespace sl::data {

struct ShadowSunOptions {
  int stride_px = 0;  // 0: chosen from the image so that about 12k pixels are visited
  double ground_tolerance_m = 0.25;
  double max_distance_m = 40.0;
  double march_m = 12.0;
  int march_steps = 48;
  double thickness_m = 3.0;
  double cover_m = 2.5;
  double dark_log = 0.4;       // a sample is dark when exp(−dark_log) below its level's lit ground
  double level_split_m = 0.075;  // ground more than this above the road is its own level
  double beta = 0.5;          // F_beta score
  double coarse_step_deg = 8.0, fine_step_deg = 2.0;
  double min_elevation_deg = 15.0, max_elevation_deg = 85.0;
  int refine_seeds = 3;
  int min_shadow_samples = 20;
  double min_score = 0.4;
  double near_best = 0.95;  // spread_deg: directions this close to the best score count as equally good
};

struct ShadowSunFit {
  bool found = false;
  glm::dvec3 direction{0.0, 1.0, 0.0};  // world, unit
  double azimuth_deg = 0.0, elevation_deg = 90.0;
  double score = 0.0;         // point-biserial correlation of the winner
  double shadow_ratio = 1.0;  // exp(median x_shadow − median x_lit) at the winner
  int ground_samples = 0, shadow_samples = 0;
  double spread_deg = 0.0;    // largest angle from the winner to a coarse direction scoring ≥ near_best × its score
  int candidates = 0;         // directions scored
  std::vector<std::array<double, 3>> coarse;  // (azimuth°, elevation°, score) of the coarse grid
  double time_ms = 0.0;
};

ShadowSunFit fit_sun_from_shadows(const Tensor& ldr, const Tensor& depth, const render::Camera& camera,
                                  const ShadowSunOptions& options = {});

// The shadow test of the fit for one sun direction, as an image [1, H, W]: 1 where a ground
// sample is blocked, 0.5 where a ground sample is lit (each sample marks its stride × stride cell),
// 0 elsewhere (not sampled, not ground, or covered).
// Same requirements and throws as fit_sun_from_shadows().
Tensor shadow_sun_mask(const Tensor& ldr, const Tensor& depth, const render::Camera& camera,
                       const glm::dvec3& sun_direction, const ShadowSunOptions& options = {});

}  // namespace sl::data
