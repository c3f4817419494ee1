// Disney principled BRDF: evaluation, lobe sampling and the matching mixture density.
// Formulas follow Burley 2012 (Sec. 5 and the BRDF-explorer "disney.brdf" shader); GGX and its
// Smith masking follow Walter et al. 2007; specular sampling draws visible normals (Heitz 2018,
// "Sampling the GGX distribution of visible normals", JCGT 7(4)).
#include "render/disney_brdf.h"

namespace sl::render::disney {
namespace {

// [0, 1] clamp that also maps NaN to 0.
float unit01(float x) { return x > 0.0f ? (x < 1.0f ? x : 1.0f) : 0.0f; }

}  // namespace

Prepared prepare(const Params& p) {
  Prepared m;
  m.base = glm::vec3(unit01(p.base_color.r), unit01(p.base_color.g), unit01(p.base_color.b));
  m.metallic = unit01(p.metallic);
  m.roughness = unit01(p.roughness);
  m.alpha = specular_alpha(m.roughness);
  m.sheen = unit01(p.sheen);
  m.clearcoat = unit01(p.clearcoat);
  m.clearcoat_alpha = clearcoat_alpha(unit01(p.clearcoat_gloss));
  // Burley: the tint is the base colour normalised to unit luminance (hue and saturation only).
  const float lum = luminance(m.base);
  const glm::vec3 tint = lum > 0.0f ? m.base / lum : glm::vec3(1.0f);
  const glm::vec3 spec_tint = glm::mix(glm::vec3(1.0f), tint, unit01(p.specular_tint));
  m.cspec0 = glm::mix(unit01(p.specular) * 0.08f * spec_tint, m.base, m.metallic);
  m.csheen = glm::mix(glm::vec3(1.0f), tint, unit01(p.sheen_tint));
  m.dielectric_f0 = 0.08f * unit01(p.specular);
  m.exact_fresnel = p.exact_fresnel;
  return m;
}

namespace {

// The cosines every lobe needs; `ok` is false for degenerate input or a direction below the
// horizon, in which case the BRDF and its density are zero.
struct Cosines {
  float nv = 0, nl = 0, nh = 0, lh = 0;
  bool ok = false;
};

// n and wo already unit (safe_normalize'd).
Cosines cosines_unit(const glm::vec3& n, const glm::vec3& wo, const glm::vec3& wi_in) {
  Cosines c;
  const glm::vec3 wi = safe_normalize(wi_in);
  c.nv = glm::dot(n, wo);
  c.nl = glm::dot(n, wi);
  if (!(c.nv > 0.0f) || !(c.nl > 0.0f)) return c;  // also rejects zero vectors (dot = 0)
  const glm::vec3 h = safe_normalize(wo + wi);      // nonzero: both lie above the horizon
  c.nh = std::max(glm::dot(n, h), 0.0f);
  c.lh = std::clamp(glm::dot(wi, h), 0.0f, 1.0f);
  c.nv = std::min(c.nv, 1.0f);
  c.nl = std::min(c.nl, 1.0f);
  c.ok = true;
  return c;
}

Cosines cosines(const glm::vec3& n, const glm::vec3& wo, const glm::vec3& wi) {
  return cosines_unit(safe_normalize(n), safe_normalize(wo), wi);
}

glm::vec3 eval_lobes(const Prepared& m, const Cosines& c) {
  // Diffuse: Burley's retro-reflection, Schlick-weighted towards F_D90 at grazing l and v.
  const float fl = schlick_weight(c.nl), fv = schlick_weight(c.nv), fh = schlick_weight(c.lh);
  const float fd90 = 0.5f + 2.0f * c.lh * c.lh * m.roughness;
  const float fd = (1.0f + (fd90 - 1.0f) * fl) * (1.0f + (fd90 - 1.0f) * fv);
  const glm::vec3 sheen = fh * m.sheen * m.csheen;
  const glm::vec3 diffuse = (1.0f - m.metallic) * (m.base * (fd / kPiF) + sheen);

  // Specular: GGX D, F towards white at grazing l·h (Schlick, or the exact dielectric curve),
  // separable Smith G with the same α.
  const float ds = ggx_d(c.nh, m.alpha);
  const float fw = m.exact_fresnel ? fresnel_weight(c.lh, m.dielectric_f0, true) : fh;
  const glm::vec3 fs = glm::mix(m.cspec0, glm::vec3(1.0f), fw);
  const float vs = smith_v1(c.nl, m.alpha) * smith_v1(c.nv, m.alpha);
  const glm::vec3 specular = ds * vs * fs;

  glm::vec3 f = diffuse + specular;
  if (m.clearcoat > 0.0f) {
    const float dr = gtr1_d(c.nh, m.clearcoat_alpha);
    const float fr = 0.04f + 0.96f * (m.exact_fresnel ? fresnel_weight(c.lh, 0.04f, true) : fh);
    const float vr = smith_v1(c.nl, kClearcoatG) * smith_v1(c.nv, kClearcoatG);
    f += glm::vec3(0.25f * m.clearcoat * dr * fr * vr);
  }
  return f;
}

LobeWeights weights(const Prepared& m, float nv) {
  // Proportional to each lobe's reflectance seen from this view; the floor on specular keeps
  // its Fresnel rim (present even with specular = 0) reachable by sampling.
  const float fv = schlick_weight(nv);
  float wd = (1.0f - m.metallic) * (luminance(m.base) + m.sheen * 0.25f);
  float ws = std::max(luminance(glm::mix(m.cspec0, glm::vec3(1.0f), fv)), 0.02f);
  float wc = 0.25f * m.clearcoat * (0.04f + 0.96f * fv);
  const float total = wd + ws + wc;
  return {wd / total, ws / total, wc / total};
}

float pdf_lobes(const Prepared& m, const LobeWeights& w, const Cosines& c) {
  float p = 0.0f;
  if (w.diffuse > 0.0f) p += w.diffuse * cosine_hemisphere_pdf(c.nl);
  // Visible-normal density G1(v)·D·(v·h)/(n·v), times the reflection Jacobian 1/(4 v·h).
  if (w.specular > 0.0f) p += w.specular * 0.5f * ggx_d(c.nh, m.alpha) * smith_v1(c.nv, m.alpha);
  // D·cos θ_h sampling, times the same Jacobian.
  if (w.clearcoat > 0.0f && c.lh > 0.0f)
    p += w.clearcoat * gtr1_d(c.nh, m.clearcoat_alpha) * c.nh / (4.0f * c.lh);
  return std::isfinite(p) ? p : 0.0f;
}

// GGX visible normal in the local frame (z = normal) for the local view direction v (z > 0).
glm::vec3 sample_ggx_visible_normal(const glm::vec3& v, float alpha, float u1, float u2) {
  const glm::vec3 vh = safe_normalize(glm::vec3(alpha * v.x, alpha * v.y, v.z));  // hemisphere config
  const float len2 = vh.x * vh.x + vh.y * vh.y;
  const glm::vec3 t1 = len2 > 0.0f ? glm::vec3(-vh.y, vh.x, 0.0f) / std::sqrt(len2) : glm::vec3(1, 0, 0);
  const glm::vec3 t2 = glm::cross(vh, t1);
  const float r = std::sqrt(u1), phi = 2.0f * kPiF * u2;
  const float p1 = r * std::cos(phi);
  const float s = 0.5f * (1.0f + vh.z);
  const float p2 = (1.0f - s) * std::sqrt(std::max(0.0f, 1.0f - p1 * p1)) + s * r * std::sin(phi);
  const glm::vec3 nh = p1 * t1 + p2 * t2 + std::sqrt(std::max(0.0f, 1.0f - p1 * p1 - p2 * p2)) * vh;
  return safe_normalize(glm::vec3(alpha * nh.x, alpha * nh.y, std::max(0.0f, nh.z)));
}

// GTR1 half vector by inverting its cos θ_h CDF: cos² = (1 − α^(2(1−u))) / (1 − α²).
glm::vec3 sample_gtr1_normal(float alpha, float u1, float u2) {
  const float a2 = alpha * alpha;
  const float cos2 = std::clamp((1.0f - std::pow(a2, 1.0f - u1)) / (1.0f - a2), 0.0f, 1.0f);
  const float cos_t = std::sqrt(cos2), sin_t = std::sqrt(1.0f - cos2);
  const float phi = 2.0f * kPiF * u2;
  return {sin_t * std::cos(phi), sin_t * std::sin(phi), cos_t};
}

}  // namespace

LobeWeights lobe_weights(const Params& p, float n_dot_wo) {
  return weights(prepare(p), std::clamp(n_dot_wo, 0.0f, 1.0f));
}

glm::vec3 eval(const Params& p, const glm::vec3& n, const glm::vec3& wo, const glm::vec3& wi) {
  const Cosines c = cosines(n, wo, wi);
  if (!c.ok) return glm::vec3(0.0f);
  const glm::vec3 f = eval_lobes(prepare(p), c);
  return all_finite(f) ? f : glm::vec3(0.0f);
}

DiffuseControl diffuse_control(const Params& p, float n_dot_v) {
  const Prepared m = prepare(p);
  DiffuseControl d;
  d.kappa = m.roughness - 0.5f;
  d.c = (1.0f - m.metallic) * m.base / kPiF * (1.0f + d.kappa * schlick_weight(n_dot_v));
  return d;
}

float pdf(const Params& p, const glm::vec3& n, const glm::vec3& wo, const glm::vec3& wi) {
  const Cosines c = cosines(n, wo, wi);
  if (!c.ok) return 0.0f;
  const Prepared m = prepare(p);
  return pdf_lobes(m, weights(m, c.nv), c);
}

Point point(const Params& p, const glm::vec3& n, const glm::vec3& wo) {
  Point q;
  q.n = safe_normalize(n);
  q.wo = safe_normalize(wo);
  q.nv = glm::dot(q.n, q.wo);
  q.ok = q.nv > 0.0f;
  q.m = prepare(p);
  q.w = weights(q.m, std::min(q.nv, 1.0f));
  q.frame = Frame(q.n);
  return q;
}

Sample evaluate(const Point& q, const glm::vec3& wi) {
  Sample s;
  s.wi = wi;
  const Cosines c = cosines_unit(q.n, q.wo, wi);
  if (!c.ok) return s;
  // c.nv = min(n·wo, 1), as q.w's.
  s.pdf = pdf_lobes(q.m, q.w, c);
  const glm::vec3 f = eval_lobes(q.m, c);
  s.f = all_finite(f) ? f : glm::vec3(0.0f);
  return s;
}

Sample evaluate(const Params& p, const glm::vec3& n, const glm::vec3& wo, const glm::vec3& wi) {
  return evaluate(point(p, n, wo), wi);
}

Sample sample(const Point& q, float u1, float u2, float u3) {
  Sample s;
  if (!q.ok) return s;
  const Prepared& m = q.m;
  const LobeWeights& w = q.w;
  glm::vec3 wi;
  if (u3 < w.diffuse) {
    wi = q.frame.to_world(cosine_hemisphere(u1, u2));
  } else {
    const bool coat = u3 >= w.diffuse + w.specular && w.clearcoat > 0.0f;
    const glm::vec3 h_local = coat ? sample_gtr1_normal(m.clearcoat_alpha, u1, u2)
                                   : sample_ggx_visible_normal(q.frame.to_local(q.wo), m.alpha, u1, u2);
    const glm::vec3 h = q.frame.to_world(h_local);
    const float vh = glm::dot(q.wo, h);
    if (!(vh > 0.0f)) return s;  // a back-facing microfacet cannot reflect wo
    wi = 2.0f * vh * h - q.wo;
  }
  wi = safe_normalize(wi);  // f and pdf below are those of exactly the returned direction
  const Cosines c = cosines_unit(q.n, q.wo, wi);
  if (!c.ok) return s;  // reflected below the horizon: the sample is lost, not re-drawn
  s.pdf = pdf_lobes(m, w, c);
  if (!(s.pdf > 0.0f)) return Sample{};
  s.wi = wi;
  s.f = eval_lobes(m, c);
  if (!all_finite(s.f)) return Sample{};
  return s;
}

Sample sample(const Params& p, const glm::vec3& n, const glm::vec3& wo, float u1, float u2, float u3) {
  return sample(point(p, n, wo), u1, u2, u3);
}

}  // namespace sl::render::disney
