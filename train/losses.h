// The training losses of Sec 3.4, each a differentiable function of tape tensors returning a
// scalar. Every loss is finite with finite gradients for any finite input: logs are taken of
// clamped or shifted values, normalisations are guarded, and acos's gradient is bounded
// (autodiff/unary.h floors 1 − x² for acos).
//
// Conventions: "mean" is over all elements (or over the valid / masked ones, with a floor of 1
// on the count so an empty mask gives 0, not NaN). Radiance is exposure-normalised
// (sky_autoencoder.h), so LDR(L) = clip(L^(1/2.2), 0, 1).
#pragma once
#include "autodiff/tensor.h"

namespace sl::train {

// LogEncodedL2(x̂, x) = mean (log(1 + x̂) − log(1 + x))² (Sec 3.4), x̂, x ≥ 0.
Tensor log_encoded_l2(const Tensor& pred, const Tensor& target);
// The same with the prediction given as log x̂ (log(1 + e^y) = softplus(y): no overflow).
Tensor log_encoded_l2_from_log(const Tensor& log_pred, const Tensor& target);
// A range in the same encoding, for a quantity with no label but a plausible span [lo, hi]
// (0 ≤ lo ≤ hi): mean over elements of d², d = how far log(1 + x̂) lies outside
// [log(1 + lo), log(1 + hi)] (0 inside), with x̂ = e^y given as y = log x̂.
Tensor log_encoded_range_l2_from_log(const Tensor& log_pred, double lo, double hi);

// L1 angular error: mean over rows of acos(clamp(â·a, −1, 1)) in radians, â and a [N, 3]
// (unit; both are normalised with a guard first).
Tensor angular_l1(const Tensor& pred_dir, const Tensor& target_dir);

// The sun direction as elevation and azimuth: mean over rows of |θ̂ − θ| + cos θ·|φ̂ − φ| in
// radians, θ = atan2(y, √(x² + z²)) the elevation and φ the azimuth (render/equirect.h), â and a
// [N, 3] (any length; a zero prediction is guarded). The azimuth term is the wrapped angle between
// the horizontal parts, weighted by the target's cos θ (the arc it spans on the sphere).
// Why not angular_l1 for a predictor that sees a crop: when the image leaves the azimuth
// uncertain, the direction minimising the expected angle moves up toward the zenith (for
// azimuths spread over a ring, the zenith itself), so the predicted elevation is biased high
// and, near the zenith, the azimuth gets almost no gradient. Here the elevation is judged on its
// own and the azimuth keeps a full-strength gradient. Measured at the release budget it trained a
// worse predictor than angular_l1 (docs/RESULTS.md), so it is an option, not the default.
Tensor elevation_azimuth_l1(const Tensor& pred_dir, const Tensor& target_dir);

Tensor l1(const Tensor& pred, const Tensor& target);
// Σ |p − t|·m / max(Σ m·C, 1) where mask broadcasts to pred (C = pred.numel / mask.numel
// after broadcasting the mask's missing channel dims).
Tensor masked_l1(const Tensor& pred, const Tensor& target, const Tensor& mask);

// Differentiable LDR of the paper: clip(L^(1/2.2), 0, 1), with L floored at 1e-6 so the
// derivative of the power stays finite at 0.
Tensor ldr_from_hdr(const Tensor& hdr);

// Volume branch (Sec 3.4, "Lighting volume branch loss"): mean squared error between the LDR
// of the queried radiance [.., 3] and the captured LDR [.., 3].
Tensor radiance_l2(const Tensor& radiance, const Tensor& target_ldr);

// Depth consistency: the alpha-rendered depth normalised by the opacity, d̂ = depth / max(1 − τ,
// 1e-3), against the true distance along the ray, as mean |log(1 + d̂) − log(1 + d)| over rays
// with a valid (finite, > 0) target; 0 when none is valid. depth, transmittance, target [R] or
// [N, R]; invalid targets may be 0, NaN or inf.
Tensor depth_consistency(const Tensor& depth, const Tensor& transmittance, const Tensor& target_distance);

// Sky separation: BCE between τ_K and the sky mask (1 = sky), computed as
// −mean(m log(τ + ε) + (1 − m) log(1 − τ + ε)), ε = 1e-4, so τ ∈ {0, 1} stays finite and still
// has a gradient.
Tensor sky_separation_bce(const Tensor& transmittance, const Tensor& sky_mask);

// Binary cross-entropy on logits z [N] against labels y [N] in [0, 1]: mean(softplus(z) − y·z),
// finite for any finite z (softplus never overflows). The domain classifier's loss
// (loss.domain_adversarial, train/lighting_stage.h).
Tensor bce_with_logits(const Tensor& logits, const Tensor& labels);

// Adversarial (Sec 3.4): the predictor minimises L_adv = −mean D(I_edit); the discriminator
// the hinge loss mean relu(1 − D(real)) + mean relu(1 + D(fake)).
Tensor generator_adversarial(const Tensor& d_fake);
Tensor discriminator_hinge(const Tensor& d_real, const Tensor& d_fake);

}  // namespace sl::train
