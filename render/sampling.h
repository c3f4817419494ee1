// Small Monte Carlo sampling helpers shared by the BRDF and the path tracer.
//
// Contract: every function is pure and branch-safe for any input in [0, 1) (u = 1 is also
// accepted). Directions are unit vectors in the local frame of an orthonormal basis whose
// third axis is the surface normal. Densities are per unit solid angle (1/sr).
#pragma once
#include <algorithm>
#include <cmath>

#include <glm/glm.hpp>

#include "util/math.h"

namespace sl::render {

// Orthonormal basis around a unit vector n (Duff et al. 2017, "Building an orthonormal basis,
// revisited"): branchless and continuous except on the n.z = -1 seam, which it handles.
struct Frame {
  glm::vec3 t, b, n;

  explicit Frame(const glm::vec3& normal) : n(normal) {
    const float sign = std::copysign(1.0f, n.z);
    const float a = -1.0f / (sign + n.z);
    const float c = n.x * n.y * a;
    t = glm::vec3(1.0f + sign * n.x * n.x * a, sign * c, -sign * n.x);
    b = glm::vec3(c, sign + n.y * n.y * a, -n.y);
  }
  glm::vec3 to_local(const glm::vec3& v) const { return {glm::dot(v, t), glm::dot(v, b), glm::dot(v, n)}; }
  glm::vec3 to_world(const glm::vec3& v) const { return v.x * t + v.y * b + v.z * n; }
};

// Shirley-Chiu concentric map of [0,1)² onto the unit disk: area preserving, low distortion.
inline glm::vec2 concentric_disk(float u1, float u2) {
  const float x = 2.0f * u1 - 1.0f, y = 2.0f * u2 - 1.0f;
  if (x == 0.0f && y == 0.0f) return {0.0f, 0.0f};
  float r, phi;
  if (std::abs(x) > std::abs(y)) {
    r = x;
    phi = (kPiF / 4.0f) * (y / x);
  } else {
    r = y;
    phi = (kPiF / 2.0f) - (kPiF / 4.0f) * (x / y);
  }
  return {r * std::cos(phi), r * std::sin(phi)};
}

// Malley's method: cosine-weighted hemisphere direction (local frame), density cos θ / π.
inline glm::vec3 cosine_hemisphere(float u1, float u2) {
  const glm::vec2 d = concentric_disk(u1, u2);
  const float z = std::sqrt(std::max(0.0f, 1.0f - d.x * d.x - d.y * d.y));
  return {d.x, d.y, z};
}
inline float cosine_hemisphere_pdf(float cos_theta) { return cos_theta > 0.0f ? cos_theta / kPiF : 0.0f; }

// Veach 1997, Sec. 9.2.4: power heuristic with β = 2 for one sample from each of two strategies.
inline float power_heuristic(float pdf_this, float pdf_other) {
  const float a = pdf_this * pdf_this, b = pdf_other * pdf_other;
  if (!(a > 0.0f)) return 0.0f;
  if (!std::isfinite(a)) return 1.0f;  // a delta-like density dominates
  return a / (a + b);
}

// Unit vector, or zero when the input has no usable direction (zero, denormal or non-finite).
inline glm::vec3 safe_normalize(const glm::vec3& v) {
  const float len2 = glm::dot(v, v);
  if (!(len2 > 1e-30f) || !std::isfinite(len2)) return glm::vec3(0.0f);
  return v / std::sqrt(len2);
}

inline bool all_finite(const glm::vec3& v) { return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z); }

}  // namespace sl::render
