// Progressive rendering to a sample, time or noise budget: the loop shared by
// `streetlight-render` and the street generator.
//
// A RenderPass(seed, sample_offset, spp) returns the [3, H, W] mean of samples
// [sample_offset, sample_offset + spp) of every pixel (PathTracer::render with those options,
// or any image loop over PathTracer::radiance). render_progressive() calls it with doubling
// pass sizes, so each seed's samples form one continued stratified sequence, and stops at the
// first of: `max_spp` samples per pixel, `seconds` of wall time (a pass that is predicted to
// overrun the budget is not started; at least one pass always runs), or an estimated noise
// at or below `target_noise`.
//
// Noise: with `two_seeds` the samples are split evenly between two independent seeds
// (seed and hash(seed)), and the noise of their mean is estimated from the two half images as
//   noise = sqrt(mean over pixels and channels of ((ldr(a) − ldr(b)) / 2)²),
// ldr(x) = clip((exposure·x)^(1/2.2), 0, 1): the standard deviation of a displayed pixel value
// (0-1 scale; 1/255 is one 8-bit level). `exposure` 0 picks the exposure that maps the median
// luminance of the current image to `auto_median_ldr` (the generator's LDR rule). Without
// `two_seeds` (one sequence, a little less noisy at equal samples) noise is not estimated
// (reported as −1) and `target_noise` must be 0.
// Determinism: the passes, and so the image, depend only on (seed, spp reached, two_seeds);
// a rerun with max_spp = result.spp and no time or noise budget reproduces it bitwise.
// Throws: sl::Error for max_spp < 1 (or < 2 with two_seeds), a negative budget, or a noise
// target without two_seeds; whatever the pass throws.
#pragma once
#include <cstdint>
#include <functional>

#include "autodiff/tensor.h"

namespace sl::render {

using RenderPass = std::function<Tensor(uint64_t seed, int64_t sample_offset, int spp)>;

struct ProgressiveOptions {
  uint64_t seed = 0;
  int max_spp = 64;
  double seconds = 0.0;       // 0 = no time budget
  double target_noise = 0.0;  // 0 = no noise target (needs two_seeds)
  bool two_seeds = false;
  double exposure = 0.0;  // for the noise metric; 0 = automatic
  double auto_median_ldr = 0.4;
  // Without a time or noise budget, render all max_spp samples in one pass per seed (no
  // progress reports in between, no per-pass overhead). Same samples, same image up to float
  // rounding of the pass averages.
  bool single_pass_without_budget = false;
};

struct ProgressiveStatus {
  int spp = 0;           // samples per pixel so far
  int max_spp = 0;
  double seconds = 0.0;  // wall time so far
  double noise = -1.0;   // LDR noise estimate, −1 when not estimated
};

struct ProgressiveResult {
  Tensor radiance;  // [3, H, W] mean of all samples
  ProgressiveStatus status;
};

ProgressiveResult render_progressive(const RenderPass& pass, const ProgressiveOptions& options,
                                     const std::function<void(const ProgressiveStatus&)>& on_pass = {});

// The LDR noise of the mean of two independent estimates a and b ([3, H, W] F32).
double ldr_noise(const Tensor& a, const Tensor& b, double exposure);

}  // namespace sl::render
