// Spherical Gaussian lobes (Sec 3.1): G(v) = c · exp(−(1 − v·μ)/σ²), with sharpness λ = 1/σ².
//
// Contract: evaluated in the stable form 1 − v·μ̂ = |v − μ̂|²/2 (v and μ̂ unit), so the exponent
// is ≤ 0 and never overflows; sharpness from 1e-3 to 1e4 and beyond is safe. μ is normalised
// here with a guarded length (max(|μ|, kAxisEps)), so a zero axis gives a finite lobe and a
// finite gradient. The gradient helpers return d/dc, d/dλ and d/dμ (through the
// normalisation) for an upstream gradient on the RGB value.
#pragma once
#include <cmath>

namespace sl::render::sg {

constexpr double kAxisEps = 1e-8;

template <class T>
struct Lobe {
  T c[3];
  T mu[3];
  T sharpness;  // λ = 1/σ²
};

template <class T>
struct LobeEval {
  T value[3];
  T e;        // exp(−λ|v − μ̂|²/2)
  T dist2;    // |v − μ̂|²
  T muhat[3];
  T mu_len;   // max(|μ|, kAxisEps)
};

// The lobe's unit axis μ̂ = μ / max(|μ|, kAxisEps); returns the guarded length. A caller that
// evaluates one lobe in many directions can store μ̂ once: unit_axis_exponent() on it gives
// exponent()'s bits.
template <class T>
inline T unit_axis(const T mu[3], T muhat[3]) {
  const T len = std::sqrt(mu[0] * mu[0] + mu[1] * mu[1] + mu[2] * mu[2]);
  const T mu_len = len > T(kAxisEps) ? len : T(kAxisEps);
  for (int i = 0; i < 3; ++i) muhat[i] = mu[i] / mu_len;
  return mu_len;
}

// |v − μ̂|² for a unit axis μ̂.
template <class T>
inline T axis_distance2(const T muhat[3], const T v[3]) {
  T dist2 = 0;
  for (int i = 0; i < 3; ++i) {
    const T d = v[i] - muhat[i];
    dist2 += d * d;
  }
  return dist2;
}

// The lobe's normalised axis and |v − μ̂|² into r (the part of eval() before the exponential).
template <class T>
inline void axis_distance(const Lobe<T>& lobe, const T v[3], LobeEval<T>& r) {
  r.mu_len = unit_axis(lobe.mu, r.muhat);
  r.dist2 = axis_distance2(r.muhat, v);
}

template <class T>
inline LobeEval<T> eval(const Lobe<T>& lobe, const T v[3]) {
  LobeEval<T> r;
  axis_distance(lobe, v, r);
  r.e = std::exp(-lobe.sharpness * r.dist2 / 2);
  for (int i = 0; i < 3; ++i) r.value[i] = lobe.c[i] * r.e;
  return r;
}

// −λ|v − μ̂|²/2 for a unit axis μ̂ (from unit_axis()).
template <class T>
inline T unit_axis_exponent(const T muhat[3], T sharpness, const T v[3]) {
  return -sharpness * axis_distance2(muhat, v) / 2;
}

// eval()'s exponent −λ|v − μ̂|²/2 alone, by the same operations (for callers that take the
// exponentials of many lobes in one vectorised call).
template <class T>
inline T exponent(const Lobe<T>& lobe, const T v[3]) {
  T muhat[3];
  unit_axis(lobe.mu, muhat);
  return unit_axis_exponent(muhat, lobe.sharpness, v);
}

// Accumulates into grads (c[3], mu[3], sharpness) the gradient of Σ_i g[i]·value[i].
template <class T>
inline void backward(const Lobe<T>& lobe, const T v[3], const LobeEval<T>& r, const T g[3], T gc[3], T gmu[3],
                     T& gsharp) {
  T gv = 0;  // d/de
  for (int i = 0; i < 3; ++i) {
    gc[i] += g[i] * r.e;
    gv += g[i] * lobe.c[i];
  }
  gsharp += -gv * r.e * r.dist2 / 2;
  // d e / d μ̂ = e · λ · (v − μ̂); then through μ̂ = μ / max(|μ|, eps).
  T gmuhat[3];
  for (int i = 0; i < 3; ++i) gmuhat[i] = gv * r.e * lobe.sharpness * (v[i] - r.muhat[i]);
  const T len = std::sqrt(lobe.mu[0] * lobe.mu[0] + lobe.mu[1] * lobe.mu[1] + lobe.mu[2] * lobe.mu[2]);
  if (len > T(kAxisEps)) {
    const T dot = gmuhat[0] * r.muhat[0] + gmuhat[1] * r.muhat[1] + gmuhat[2] * r.muhat[2];
    for (int i = 0; i < 3; ++i) gmu[i] += (gmuhat[i] - dot * r.muhat[i]) / r.mu_len;
  } else {
    for (int i = 0; i < 3; ++i) gmu[i] += gmuhat[i] / r.mu_len;
  }
}

}  // namespace sl::render::sg
