// The two sums of render/insertion_mixture_pdf.h, fused where the per-ray code was fused and
// nowhere else (compiled with -ffp-contract=off).
#include "render/insertion_mixture_pdf.h"

#include <cmath>

namespace sl::render::insertion {
namespace {

#if defined(__FMA__)
float fused(float a, float b, float c) { return std::fma(a, b, c); }
#else
float fused(float a, float b, float c) { return a * b + c; }
#endif

}  // namespace

float sky_cos_elevation(const glm::vec3& l, bool sky) {
  return std::sqrt(sky ? fused(l.x, l.x, l.z * l.z) : l.x * l.x + l.z * l.z);
}

float mixture_pdf(float c_brdf, float brdf_pdf, float c_env, float env_pdf, bool sky) {
  return sky ? fused(brdf_pdf, c_brdf, c_env * env_pdf) : fused(c_env, env_pdf, c_brdf * brdf_pdf);
}

}  // namespace sl::render::insertion
