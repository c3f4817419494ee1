// Disney "principled" BRDF (Burley 2012, "Physically-based shading at Disney", Sec. 5 and the
// BRDF-explorer reference shader), the paper's foreground material (Sec. 3.3, Eq. 2).
//
// Lobes (all evaluated with unit vectors pointing AWAY from the surface):
//   diffuse   (1 − metallic)·[ base/π · (1 + (F_D90 − 1)F_L)(1 + (F_D90 − 1)F_V) + sheen ],
//             F_D90 = 0.5 + 2·roughness·(l·h)², F_x = (1 − n·x)^5 (Burley's retro-reflection)
//   specular  D_GGX(α)·F·G / (4 n·l n·v) with α = max(roughness², kMinAlpha), separable Smith G
//             for GGX (Walter et al. 2007) with the same α, Schlick F from
//             C_spec0 = lerp(0.08·specular·lerp(1, tint, specular_tint), base, metallic)
//   clearcoat 0.25·clearcoat · D_GTR1(α_c)·F_c·G_c / (4 n·l n·v), α_c = lerp(0.1, 0.001, gloss),
//             F_c Schlick with F0 = 0.04 (IOR 1.5), Smith G with α = 0.25.
// The model is Burley's, not an energy-conserving one: diffuse and specular are added without
// coupling, so directional albedo exceeds 1 by a few per cent at grazing views (measured in
// tests/render/disney_brdf_test.cpp), and single-scattering GGX loses energy at high roughness.
//
// API:
//   eval(p, n, wo, wi)  -> f (the BRDF only, 1/sr; the caller multiplies by cos θ_i = n·wi).
//   sample(p, n, wo, u1, u2, u3) -> {wi, f, pdf}: u3 picks a lobe (weights from lobe_weights),
//       u1, u2 draw the direction: cosine-weighted for diffuse, GGX visible normals (Heitz 2018)
//       for specular, D·cos for the clearcoat GTR1. f = eval(wi), pdf = pdf(wi) (the full
//       mixture, solid angle). A sample below the horizon returns pdf = 0 and f = 0.
//   pdf(p, n, wo, wi)   -> the mixture density sample() draws from (1/sr).
// n need not be unit; wo, wi need not be unit. Zero-length or non-finite n, wo or wi, and wo or
// wi at or below the horizon of n, give f = 0 and pdf = 0 — never NaN or Inf. Parameters
// (base colour channels included) are clamped to [0, 1], NaN to 0, so no input makes the output
// non-finite.
// eval is reciprocal: eval(wo, wi) == eval(wi, wo) (the lobe-selection weights of sample/pdf
// depend on wo, as they must; f does not).
#pragma once
#include <algorithm>
#include <cmath>

#include <glm/glm.hpp>

#include "render/sampling.h"

namespace sl::render::disney {

inline constexpr float kMinAlpha = 1e-3f;  // roughness 0 becomes a very sharp, finite GGX lobe

struct Params {
  glm::vec3 base_color{0.8f};  // linear RGB
  float metallic = 0.0f;
  float roughness = 0.5f;
  float specular = 0.5f;  // 0.5 gives F0 = 0.04, the glTF dielectric
  float specular_tint = 0.0f;
  float sheen = 0.0f;
  float sheen_tint = 0.5f;
  float clearcoat = 0.0f;
  float clearcoat_gloss = 1.0f;
  // false: Schlick's Fresnel (Burley's). true: the exact dielectric Fresnel of the IOR that
  // gives F0 = 0.08·specular (1.5 for the clearcoat), interpolated towards C_spec0 as Blender
  // Cycles' principled BSDF does: F = C_spec0 + (1 − C_spec0)·(F_exact(l·h) − F0)/(1 − F0).
  bool exact_fresnel = false;
};

struct Sample {
  glm::vec3 wi{0.0f};  // unit, world
  glm::vec3 f{0.0f};   // BRDF value at wi (no cosine)
  float pdf = 0.0f;    // solid-angle density; 0 marks a failed sample
};

// ---- scalar building blocks (reused by the differentiable insertion renderer)

// Schlick's weight (1 − cos)^5, cos clamped to [0, 1].
inline float schlick_weight(float cos_theta) {
  const float m = std::clamp(1.0f - cos_theta, 0.0f, 1.0f);
  const float m2 = m * m;
  return m2 * m2 * m;
}

// Exact Fresnel reflectance of unpolarised light at a dielectric boundary of relative IOR
// eta > 0 (light arriving from the outside), cos_theta the cosine of incidence; 1 under total
// internal reflection (eta < 1 at grazing angles).
inline float fresnel_dielectric(float cos_theta, float eta) {
  const float c = std::clamp(std::abs(cos_theta), 0.0f, 1.0f);
  float g = eta * eta - 1.0f + c * c;
  if (!(g > 0.0f)) return 1.0f;
  g = std::sqrt(g);
  const float a = (g - c) / (g + c);
  const float b = (c * (g + c) - 1.0f) / (c * (g - c) + 1.0f);
  return std::clamp(0.5f * a * a * (1.0f + b * b), 0.0f, 1.0f);
}
// The IOR whose normal-incidence reflectance is f0 in [0, 1): (1 + √f0) / (1 − √f0).
inline float ior_from_f0(float f0) {
  const float r = std::sqrt(std::clamp(f0, 0.0f, 0.99f));
  return (1.0f + r) / (1.0f - r);
}
// The weight that takes F0 to 1: Schlick's (1 − cos)^5, or the exact curve normalised,
// (F_exact(cos) − F0)/(1 − F0) for the IOR of f0.
inline float fresnel_weight(float cos_theta, float f0, bool exact) {
  if (!exact) return schlick_weight(cos_theta);
  const float f = std::clamp(f0, 0.0f, 0.99f);
  return std::clamp((fresnel_dielectric(cos_theta, ior_from_f0(f)) - f) / (1.0f - f), 0.0f, 1.0f);
}

// Trowbridge-Reitz / GGX normal distribution (Walter et al. 2007, Eq. 33):
//   D = α² / (π (cos²θ_h (α² − 1) + 1)²), written as α² cos² + sin² to avoid cancellation.
inline float ggx_d(float n_dot_h, float alpha) {
  if (!(n_dot_h > 0.0f)) return 0.0f;
  const float a2 = alpha * alpha;
  const float c2 = std::min(n_dot_h * n_dot_h, 1.0f);
  const float d = a2 * c2 + (1.0f - c2);
  return a2 / (kPiF * d * d);
}

// Burley's GTR with γ = 1 (the clearcoat lobe): D = (α² − 1) / (π ln(α²) (1 + (α² − 1) cos²θ_h)).
inline float gtr1_d(float n_dot_h, float alpha) {
  if (!(n_dot_h > 0.0f)) return 0.0f;
  const float a2 = alpha * alpha;
  if (a2 >= 1.0f) return 1.0f / kPiF;
  const float c2 = std::min(n_dot_h * n_dot_h, 1.0f);
  return (a2 - 1.0f) / (kPiF * std::log(a2) * (1.0f + (a2 - 1.0f) * c2));
}

// Smith masking for GGX (Walter et al. 2007, Eq. 34): G1 = 2 cos / (cos + sqrt(α² + (1 − α²) cos²)).
inline float smith_g1(float n_dot_v, float alpha) {
  if (!(n_dot_v > 0.0f)) return 0.0f;
  const float a2 = alpha * alpha;
  const float c = std::min(n_dot_v, 1.0f);
  return 2.0f * c / (c + std::sqrt(a2 + (1.0f - a2) * c * c));
}

// G1 / (2 cos): the half of the microfacet denominator 4 n·l n·v that belongs to one direction,
// finite as cos → 0 (it tends to 1/α). D·F·smith_v1(n·l)·smith_v1(n·v) = D·F·G/(4 n·l n·v).
inline float smith_v1(float n_dot_v, float alpha) {
  if (!(n_dot_v > 0.0f)) return 0.0f;
  const float a2 = alpha * alpha;
  const float c = std::min(n_dot_v, 1.0f);
  return 1.0f / (c + std::sqrt(a2 + (1.0f - a2) * c * c));
}

inline float specular_alpha(float roughness) {
  const float r = std::clamp(roughness, 0.0f, 1.0f);
  return std::max(r * r, kMinAlpha);
}
inline float clearcoat_alpha(float gloss) {
  const float g = std::clamp(gloss, 0.0f, 1.0f);
  return 0.1f + (0.001f - 0.1f) * g;
}
inline constexpr float kClearcoatG = 0.25f;  // Burley's fixed α for the clearcoat masking

// ---- the BRDF

// Parameters clamped to their ranges, and the colours derived from them once per shading point.
struct Prepared {
  glm::vec3 base, cspec0, csheen;
  float metallic, roughness, alpha, sheen, clearcoat, clearcoat_alpha;
  float dielectric_f0;  // 0.08·specular: the IOR of the exact Fresnel option
  bool exact_fresnel;
};
Prepared prepare(const Params& p);

glm::vec3 eval(const Params& p, const glm::vec3& n, const glm::vec3& wo, const glm::vec3& wi);
Sample sample(const Params& p, const glm::vec3& n, const glm::vec3& wo, float u1, float u2, float u3);
float pdf(const Params& p, const glm::vec3& n, const glm::vec3& wo, const glm::vec3& wi);
// {wi, eval(wi), pdf(wi)} with the shared work done once (identical bits to the two calls).
Sample evaluate(const Params& p, const glm::vec3& n, const glm::vec3& wo, const glm::vec3& wi);
// The diffuse lobe as a control variate needs it (render/object_insertion.h,
// diffuse_control_variate): g(l) = c·(1 + κ·F_L), F_L = (1 − n·l)^5, with
// c = (1 − metallic)·base/π·(1 + κ·F_V) and κ = F_D90 − 1 = roughness − ½, Burley's F_D90 at
// (l·h)² = ½ (a light at the horizon, averaged over its azimuth). Parameters clamped as in eval.
struct DiffuseControl {
  glm::vec3 c{0.0f};
  float kappa = 0.0f;
};
DiffuseControl diffuse_control(const Params& p, float n_dot_v);

// Probabilities with which sample() picks the diffuse, specular and clearcoat lobes for this
// view (sum to 1; a lobe that can reflect light never gets probability 0).
struct LobeWeights {
  float diffuse, specular, clearcoat;
};
LobeWeights lobe_weights(const Params& p, float n_dot_wo);

// One shading point (p, n, wo) prepared once for many directions: the clamped parameters, unit
// n and wo, the lobe weights and the tangent frame. sample(point(p, n, wo), …) and
// evaluate(point(p, n, wo), wi) give identical bits to the per-call forms above.
struct Point {
  glm::vec3 n{0.0f}, wo{0.0f};
  float nv = 0.0f;
  bool ok = false;  // wo above the horizon of n
  Prepared m{};
  LobeWeights w{};
  Frame frame{glm::vec3(0, 0, 1)};
};
Point point(const Params& p, const glm::vec3& n, const glm::vec3& wo);
Sample sample(const Point& q, float u1, float u2, float u3);
Sample evaluate(const Point& q, const glm::vec3& wi);

}  // namespace sl::render::disney
