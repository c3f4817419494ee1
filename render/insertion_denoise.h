// Denoising of Eq. 2's Monte Carlo residual (render/object_insertion.h, "Denoising"): with the
// diffuse control variate, a pixel's colour is C + R, C = ∫g·cos·L (exact up to quadrature,
// noise-free) and R the sampled residual Σ (f·V' − g)·cos·L/p. The filter smooths only R's ratio
// to C over a (2r+1)² window, so albedo, texture and the irradiance stay per pixel:
//   R'_p = C_p ⊙ Σ_q w_pq R_q / Σ_q w_pq C_q   (per channel),
//   w_pq = exp(−(1 − n_p·n_q)/σ_n − |n_p·(x_q − x_p)|/(σ_z·z_p) − (ρ_p − ρ_q)²/(σ_v²·(v_p + v_q))),
// n the pixel's mean normal, x its mean surface point, z its depth (so the second term is q's
// distance from p's tangent plane, relative to the distance from the camera: zero along a
// slanted face, large across a step), ρ = ΣR/ΣC over channels and v that ratio's sample
// variance (so differences larger than the noise are kept). Biased where the true ratio
// changes inside the window faster than the guides detect; measured against the reference by
// streetlight-bench insert (rows denoise*). Internal to render/.
//
// Contract: a field with one ratio R/C everywhere comes back unchanged; r = 0 is the identity; a
// pixel whose window weighs no C (Σ w·C = 0 in a channel) keeps its own R there; the result
// does not depend on the thread count.
#pragma once
#include <vector>

#include <glm/glm.hpp>

#include "render/object_insertion.h"
#include "render/pixel_window.h"

namespace sl::render::insertion {

struct DenoisePixel {
  glm::vec3 residual{0.0f};  // R
  glm::vec3 control{0.0f};   // C ≥ 0
  glm::vec3 normal{0.0f};    // unit (0 when unknown: never similar)
  glm::vec3 position{0.0f};  // the surface point (world)
  float depth = 0.0f;        // camera z > 0 (0: unknown, the plane term is left out)
  float variance = 0.0f;     // of R's channel sum
};

// R' per pixel of `window` (opt.denoise_radius, denoise_normal_sigma, denoise_depth_sigma,
// denoise_variance_sigma).
std::vector<glm::vec3> denoise_residual(const std::vector<DenoisePixel>& px, const PixelWindow& window,
                                        const InsertionOptions& opt);

}  // namespace sl::render::insertion
