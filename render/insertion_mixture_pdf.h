// Two float sums of the foreground's inference sampling (render/insertion_foreground.cpp), each
// rounded exactly as the per-ray code has always rounded it, so that the sky's densities can be
// computed as one batch (EnvironmentMap::pdf_bilinear_units) without moving a bit of the output.
// Internal to render/.
//
// Why this file exists: in the per-ray loop GCC contracted these sums (-ffp-contract=fast) after
// duplicating the loop's tail per sampling technique, so a ray's rounding depended on which
// technique drew it. The batched loop writes both forms out; this file is compiled with
// -ffp-contract=off (render/CMakeLists.txt) so no further fusion is added.
//
// Contract: pure functions of their arguments. With FMA (the builds the fingerprints are taken
// with), a ray of the sky technique (sky = true) and one of the BRDF technique get:
//   sky_cos_elevation: sky √fma(x, x, z·z);           BRDF √(x·x + z·z)
//   mixture_pdf:       sky fma(b, c_brdf, c_env·e);   BRDF fma(c_env, e, c_brdf·b)
// (each product and sum rounded to float). Without FMA, both are the plain rounded forms.
#pragma once
#include <glm/glm.hpp>

namespace sl::render::insertion {

// cos(elevation) = √(x² + z²) of the unit direction l, as the per-ray code passed it to
// EnvironmentMap::pdf_bilinear_unit.
float sky_cos_elevation(const glm::vec3& l, bool sky);

// The multi-sample MIS density c_brdf · brdf_pdf + c_env · env_pdf of a ray.
float mixture_pdf(float c_brdf, float brdf_pdf, float c_env, float env_pdf, bool sky);

}  // namespace sl::render::insertion
