// The foreground's two per-technique roundings (render/insertion_mixture_pdf.h): the batched
// sky densities of light_rays() keep the output's bits only if each ray's cos(elevation) and
// mixture density are rounded as the one-ray-at-a-time code rounded them.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>

#include <glm/glm.hpp>

#include "render/insertion_mixture_pdf.h"
#include "util/random.h"

namespace sl::test {
namespace {

using render::insertion::mixture_pdf;
using render::insertion::sky_cos_elevation;

bool same_bits(float a, float b) { return std::memcmp(&a, &b, sizeof a) == 0; }

// a·b rounded once: fma with +0 is never folded into a product (it differs on −0), so GCC cannot
// contract it into the sum that follows, whatever this file's -ffp-contract.
float product(float a, float b) { return std::fma(a, b, 0.0f); }
#if defined(__FMA__)
float fused(float a, float b, float c) { return std::fma(a, b, c); }
#else
float fused(float a, float b, float c) { return product(a, b) + c; }
#endif

glm::vec3 unit_direction(uint64_t i) {
  const float z = 2.0f * uniform01f(7, i, 0) - 1.0f, phi = 6.2831853f * uniform01f(7, i, 1);
  const float r = std::sqrt(std::max(0.0f, 1.0f - z * z));
  return glm::normalize(glm::vec3(r * std::cos(phi), z, r * std::sin(phi)));
}

TEST(InsertionMixturePdf, SkyRaysFuseTheSquaresOfCosElevationAndBrdfRaysDoNot) {
  int apart = 0;
  for (uint64_t i = 0; i < 20000; ++i) {
    const glm::vec3 l = unit_direction(i);
    const float sky = std::sqrt(fused(l.x, l.x, product(l.z, l.z)));
    const float brdf = std::sqrt(product(l.x, l.x) + product(l.z, l.z));
    ASSERT_TRUE(same_bits(sky_cos_elevation(l, true), sky)) << "ray " << i;
    ASSERT_TRUE(same_bits(sky_cos_elevation(l, false), brdf)) << "ray " << i;
    apart += !same_bits(sky, brdf);
  }
#if defined(__FMA__)
  EXPECT_GT(apart, 0) << "the two forms never differ: the test no longer tells them apart";
#endif
}

TEST(InsertionMixturePdf, TheMixtureFusesTheOtherTechniquesProduct) {
  int apart = 0;
  for (const float c_brdf : {0.5f, float(3) / float(7), float(31) / float(64)}) {
    const float c_env = 1.0f - c_brdf;
    for (uint64_t i = 0; i < 20000; ++i) {
      const float b = 10.0f * uniform01f(8, i, 0), e = i % 13 == 5 ? 0.0f : 1e4f * uniform01f(8, i, 1);
      const float sky = fused(b, c_brdf, product(c_env, e)), brdf = fused(c_env, e, product(c_brdf, b));
      ASSERT_TRUE(same_bits(mixture_pdf(c_brdf, b, c_env, e, true), sky)) << "ray " << i;
      ASSERT_TRUE(same_bits(mixture_pdf(c_brdf, b, c_env, e, false), brdf)) << "ray " << i;
      apart += !same_bits(sky, brdf);
    }
  }
#if defined(__FMA__)
  EXPECT_GT(apart, 0) << "the two forms never differ: the test no longer tells them apart";
#endif
}

}  // namespace
}  // namespace sl::test
